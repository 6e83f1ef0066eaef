"""`cassie bench estimator` runs end to end and writes its flat JSON of figures."""

from __future__ import annotations

import json

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
