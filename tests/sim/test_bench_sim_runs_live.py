"""`cassie bench sim` runs the real sim process under the live runner against its peer, and
the baseline machinery (a git revision's tree, interleaved): figures come out, no timing is
judged."""

from __future__ import annotations

import json
from pathlib import Path

from tools.benchmarks import sim as bench


def test_the_live_sim_bench_reports_figures_for_this_tree_and_a_baseline(
        tmp_path: Path) -> None:
    out = tmp_path / "sim.json"
    assert bench.main(["--seconds", "1", "--warmup", "0.3", "--repeats", "1", "--contend", "0",
                       "--baseline", "HEAD", "--json", str(out)]) == 0
    fig = json.loads(out.read_text())
    for prefix in ("", "baseline_"):
        assert fig[f"{prefix}ticks"] > 500  # ~2000 a second
        assert 0 < fig[f"{prefix}cpu_share"] < 2
        assert 0 < fig[f"{prefix}tick_cpu_median_ms"] <= fig[f"{prefix}tick_cpu_p99_ms"]
        assert fig[f"{prefix}peer_received"] > 500 and fig[f"{prefix}packets_lost_by_peer"] >= 0
    assert fig["baseline_rev"] == "HEAD" and "tick_cpu_median_ratio" in fig
