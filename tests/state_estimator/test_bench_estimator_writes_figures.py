"""`cassie bench estimator` runs end to end and writes its flat JSON of figures."""

from __future__ import annotations

import json

import pytest

from tools.benchmarks.estimator import main


def test_bench_writes_timing_and_accuracy_figures(tmp_path, capsys):
    out = tmp_path / "est.json"
    assert main(["--seconds", "0.3", "--motion", "still", "--json", str(out)]) == 0
    fig = json.loads(out.read_text())
    assert fig["name"] == "estimator" and "machine" in fig
    assert fig["tick_count"] >= 600 and fig["states"] >= 600
    for key in ("tick_median_ms", "tick_p99_ms", "tick_cpu_median_ms", "vel_rmse_m_s",
                "pos_drift_per_m", "tick_over_period_ratio"):
        assert fig[key] >= 0.0, key
    assert fig["vel_rmse_m_s"] < 0.01  # standing on the holder: the estimate is still too
    assert "velocity RMSE" in capsys.readouterr().out


def test_bench_times_a_git_baseline_side_by_side(tmp_path, capsys):
    # the baseline is this repository's HEAD: same code both sides, so the ratios are near 1
    out = tmp_path / "est.json"
    assert main(["--seconds", "0.2", "--motion", "still", "--baseline", "HEAD",
                 "--json", str(out)]) == 0
    fig = json.loads(out.read_text())
    assert fig["baseline_rev"] == "HEAD" and fig["side_by_side_repeats"] == 3
    for side in ("baseline", "this"):
        assert fig[f"{side}_tick_median_ms"] > 0.0
    assert 0.2 < fig["speedup_median_ratio"] < 5.0
    # and every message of the two compared (same code: the same messages)
    assert fig["equiv_states"] >= 400 and fig["equiv_roles_differ"] == 0
    assert 0.0 <= fig["equiv_states_byte_identical_ratio"] <= 1.0
    assert "side by side: baseline HEAD" in capsys.readouterr().out


def test_bench_names_a_revision_git_does_not_know():
    with pytest.raises(SystemExit, match="no-such-rev"):
        main(["--seconds", "0.1", "--motion", "still", "--baseline", "no-such-rev"])


def test_live_bench_feeds_the_estimator_process_over_udp(tmp_path, capsys):
    # a short live run: the estimator under LiveRunner, the replayer, two subscribers; the
    # figures exist and every packet was taken (never a timing assertion: shared machines)
    out = tmp_path / "est.json"
    assert main(["--seconds", "0.3", "--motion", "still", "--live", "--live-seconds", "1",
                 "--live-repeats", "1", "--json", str(out)]) == 0
    fig = json.loads(out.read_text())
    assert fig["live_this_segments"] == 1
    for key in ("live_this_cpu_share_median_cores", "live_this_tick_cpu_median_ms",
                "live_this_tick_cpu_p99_ms", "live_this_outside_tick_cpu_per_packet_us",
                "live_this_subscribers_cpu_share_median_cores"):
        assert fig[key] > 0.0, key
    assert fig["live_this_packets_received"] >= 1900
    assert fig["live_this_packets_rejected"] == 0 and fig["live_this_estimator_resets"] == 0
    assert "live: LiveRunner on CPU 1" in capsys.readouterr().out
