"""`cassie bench segmenters --methods S3,superpixels` on a few recorded-style maps: both run on
the same maps and report run time, the IoU of the safe terrain and of the polygons, and the
polygon counts, for each terrain."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from tools.benchmarks.segmenters import main


def test_the_bench_reports_both_segmenters_per_terrain(tmp_path: Path, capsys) -> None:
    # a map of a step that the robot walks along: the origin moves a cell per frame
    frames, n, res = 4, 60, 0.025
    cols = np.arange(n)
    elevation = np.stack([np.where(cols[None, :] + k < 35, 0.0, 0.1).repeat(n, axis=0)
                          for k in range(frames)]).astype(np.float32)
    elevation[:, :5, :] = np.nan  # unseen rows
    origin = np.column_stack((np.arange(frames) * res, np.zeros(frames)))
    maps = tmp_path / "step.npz"
    np.savez(maps, elevation=elevation, origin=origin, resolution=res,
             mapping_ms=np.full(frames, 2.0))
    out = tmp_path / "bench.json"
    assert main(["--maps", f"step={maps}", "--methods", "S3,superpixels", "--hysteresis", "",
                 "--json", str(out)]) == 0
    figures = json.loads(out.read_text())
    for m in ("S3", "superpixels"):
        assert figures[f"step_{m}_wall_count"] == frames
        assert figures[f"step_{m}_cpu_max_ms"] > 0.0
        assert 0.0 <= figures[f"step_{m}_iou_min_ratio"] <= 1.0
        assert 0.0 <= figures[f"step_{m}_decomposition_iou_min_ratio"] <= 1.0
        assert figures[f"step_{m}_polygons_max_count"] >= 2  # both levels
    assert "step_EM_cupy_wall_count" not in figures  # not asked for
    assert "step superpixels polygons median / max" in capsys.readouterr().out
