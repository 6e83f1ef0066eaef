"""`cassie bench s3` runs end to end and writes its flat JSON (figures are not asserted)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from tools.benchmarks import s3 as bench


def test_bench_writes_stage_times_and_iou_for_every_sequence(tmp_path: Path) -> None:
    out = tmp_path / "s3.json"
    assert bench.main(["--frames", "4", "--seed", "1", "--json", str(out)]) == 0
    fig = json.loads(out.read_text())
    assert fig["name"] == "s3" and fig["machine"]
    for stage in ("inpainting", "criteria", "cleanup", "decomposition", "plane_fit", "total",
                  "mapping"):
        assert fig[f"{stage}_median_ms"] >= 0.0 and fig[f"{stage}_max_ms"] >= 0.0
    for seq in ("stairs", "stones", "stairs-mapped", "stones-mapped"):
        assert fig[f"{seq}_safe_iou_count"] == 3
        assert 0.0 <= fig[f"{seq}_safe_iou_median_ratio"] <= 1.0


def test_bench_reads_recorded_maps(tmp_path: Path) -> None:
    maps = tmp_path / "maps.npz"
    elev = np.zeros((3, 40, 40))
    elev[:, :, 20:] = 0.15
    np.savez(maps, elevation=elev, origin=np.zeros((3, 2)), resolution=0.025)
    out = tmp_path / "s3.json"
    assert bench.main(["--maps", str(maps), "--json", str(out)]) == 0
    fig = json.loads(out.read_text())
    assert fig["safe_iou_median_ratio"] == 1.0 and fig["total_count"] == 3
