"""`cassie bench s3`: per-stage S3 times and frame-to-frame IoU (Section VIII-D) on sequences of
elevation maps: synthetic walks over stairs and stepping stones (noise, NaN holes, height drift,
a map that moves with the robot), the same walks mapped from ray-marched depth frames through
the elevation map (camera, drift correction, occlusions), or recorded maps from an .npz file.

The figures are measured, never asserted: the budget is 33 ms worst case (one camera frame),
with 10 ms the aim.
"""

from __future__ import annotations

import argparse
import dataclasses
import gc
import os
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from processes.perception import ElevationMap, ElevationMapParams
from processes.s3 import STAGES, S3Params, S3Pipeline
from processes.s3.metrics import coverage_mask, frame_iou
from tools.benchmarks.common import print_table, progress, summarize, write_json
from tools.testbed import s3_scenes as syn

REPO = Path(__file__).resolve().parents[2]
DEFAULT_CONFIG = REPO / "hw_config" / "gains" / "s3.yaml"
MAP_CONFIG = REPO / "hw_config" / "gains" / "elevation_map.yaml"
BUDGET_MS = 33.0
AIM_MS = 10.0
TERRAINS = {
    "stairs": lambda seed: syn.stairs(start_x=0.0, rise=0.1, run=0.4, steps=6),
    "stones": lambda seed: syn.stepping_stones(seed=seed, start_x=0.0),
}
SEQUENCES = (*TERRAINS, *(f"{t}-mapped" for t in TERRAINS))

# (elevation, origin, time, mapping ms or nan, lowest layer or None)
Sequence = Iterator[tuple[np.ndarray, np.ndarray, float, float, np.ndarray | None]]


def _synthetic(name: str, frames: int, seed: int, resolution: float, cells: int) -> Sequence:
    """Maps rendered straight from the terrain (noise, holes, drift): S3 alone."""
    for f in syn.walk(TERRAINS[name](seed), frames, seed=seed, shape=(cells, cells),
                      resolution=resolution):
        yield f.elevation, f.origin_xy, f.time_s, float("nan"), None


def _mapped(name: str, frames: int, seed: int, params: ElevationMapParams) -> Sequence:
    """Depth frames through the elevation map; the map update (recentre, stance-foot drift
    correction, back-projection, Kalman update) is timed as the `mapping` stage. The map is
    handed to S3 as is (a copy costs microseconds and the process shell publishes one)."""
    emap = ElevationMap(params)
    for f in syn.depth_walk(TERRAINS[name](seed), frames, seed=seed):
        t0 = time.perf_counter()
        emap.recenter(f.robot_xy)
        emap.apply_drift_correction(f.stance_foot)        # Section VII-B, before the update
        emap.update_from_depth(f.depth, f.fx, f.fy, f.cx, f.cy, f.camera_pos,
                               f.camera_quat_wxyz, time_s=f.time_s)
        ms = (time.perf_counter() - t0) * 1e3
        yield emap.elevation, emap.origin.copy(), f.time_s, ms, emap.lowest


def _recorded(path: str, frames: int) -> tuple[Sequence, float]:
    """Maps from an .npz with `elevation` (F, R, C), `origin` (F, 2) and `resolution`, and
    optionally `time` (F,) and `lowest` (F, R, C)."""
    data = np.load(path)
    elev, origin = data["elevation"], data["origin"]
    res = float(data["resolution"])
    times = data["time"] if "time" in data else np.arange(len(elev)) / 30.0
    n = min(frames, len(elev)) if frames > 0 else len(elev)
    low = data.get("lowest")
    return ((elev[k], origin[k], float(times[k]), float("nan"),
             None if low is None else low[k]) for k in range(n)), res


def run_sequence(frames: Sequence, resolution: float, params: S3Params, total: int | None = None,
                 desc: str = "S3 frames") -> dict[str, list[float]]:
    """Run S3 over one sequence; per-frame stage times, IoUs and polygon counts (``total``
    and ``desc``: the frames expected and the name, for the progress bar)."""
    pipe = S3Pipeline(params)
    out: dict[str, list[float]] = {s: [] for s in (*STAGES, "total", "wall", "cpu", "mapping",
                                                    "perception", "safe_iou",
                                                    "decomposition_iou", "polygons",
                                                    "acd_cuts", "whittle_cuts", "dropped")}
    prev = None
    bar = progress(total, desc, unit="frame")
    for elevation, origin, _t, mapping_ms, lowest in frames:
        c0 = time.thread_time()
        t0 = time.perf_counter()
        r = pipe.process(elevation, resolution, origin, lowest=lowest)
        wall = (time.perf_counter() - t0) * 1e3
        # CPU time of this thread: what S3 costs, without the waits a busy machine adds
        out["cpu"].append((time.thread_time() - c0) * 1e3)
        for s in (*STAGES, "total"):
            out[s].append(r.times_ms.get(s, 0.0))
        out["wall"].append(wall)
        if np.isfinite(mapping_ms):
            out["mapping"].append(mapping_ms)
            out["perception"].append(mapping_ms + wall)
        out["polygons"].append(float(len(r.footholds)))
        for key in ("acd_cuts", "whittle_cuts", "dropped"):
            out[key].append(float(r.stats.get(key, 0)))
        cover = coverage_mask([f.vertices_xy for f in r.footholds], r.safe_mask.shape,
                              resolution, origin)
        if prev is not None:
            out["safe_iou"].append(frame_iou(prev[0], prev[2], r.safe_mask, origin, resolution))
            out["decomposition_iou"].append(frame_iou(prev[1], prev[2], cover, origin,
                                                      resolution))
        prev = (r.safe_mask, cover, np.asarray(origin))
        # here, before the next frame is made (and the map update timed inside its generator)
        bar.update(1)
    bar.close()
    return out


def _ratio_stats(samples: list[float], prefix: str) -> dict[str, float]:
    a = np.asarray(samples, dtype=float)
    a = a[np.isfinite(a)]
    if a.size == 0:
        return {f"{prefix}_count": 0}
    return {
        f"{prefix}_count": int(a.size),
        f"{prefix}_median_ratio": float(np.median(a)),
        f"{prefix}_p5_ratio": float(np.percentile(a, 5.0)),
        f"{prefix}_min_ratio": float(a.min()),
    }


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark, print tables, optionally write the flat JSON; returns 0."""
    ap = argparse.ArgumentParser(prog="cassie bench s3", description=__doc__.splitlines()[0])
    ap.add_argument("--json", metavar="FILE", help="write the figures as one flat JSON object")
    ap.add_argument("--frames", type=int, default=300, help="frames per sequence (30 Hz)")
    ap.add_argument("--seed", type=int, default=0, help="seed of noise, holes and stones")
    ap.add_argument("--sequences", default=",".join(SEQUENCES),
                    help=f"comma-separated sequences from {', '.join(SEQUENCES)}")
    ap.add_argument("--maps", metavar="NPZ", help="recorded maps instead of synthetic ones")
    ap.add_argument("--config", default=str(DEFAULT_CONFIG), help="S3 parameter file")
    ap.add_argument("--profile", default=None, help="profile in the parameter file")
    args = ap.parse_args(argv)

    from runtime.params import load  # --profile: a variant of the files (none: the top level)
    params = load(S3Params, args.config, args.profile)
    map_params = load(ElevationMapParams, MAP_CONFIG, args.profile)
    map_params = dataclasses.replace(map_params, decimation=1)   # frames come decimated
    resolution, cells = map_params.resolution_m, map_params.cells
    if args.maps:
        seq, resolution = _recorded(args.maps, args.frames)
        runs = {"recorded": (seq, resolution)}
    else:
        names = [s.strip() for s in args.sequences.split(",") if s.strip()]
        for s in names:
            if s not in SEQUENCES:
                ap.error(f"unknown sequence {s!r} (allowed: {', '.join(sorted(SEQUENCES))})")
        runs = {}
        for s in names:
            if s.endswith("-mapped"):
                runs[s] = (_mapped(s.removesuffix("-mapped"), args.frames, args.seed,
                                   map_params), resolution)
            else:
                runs[s] = (_synthetic(s, args.frames, args.seed, resolution, cells), resolution)

    gc.collect()
    gc.freeze()                             # as the process shells do: no old-generation scans
    figures_load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    per_seq: dict[str, dict[str, list[float]]] = {}
    for name, (seq, res) in runs.items():
        # (a recorded file may hold fewer frames: the bar then ends short)
        per_seq[name] = run_sequence(seq, res, params, args.frames if args.frames > 0 else None,
                                     name)

    merged: dict[str, list[float]] = {k: [] for k in next(iter(per_seq.values()))}
    for res_seq in per_seq.values():
        for k, v in res_seq.items():
            merged[k].extend(v)

    figures: dict[str, object] = {
        "description": "S3 per-stage time and frame-to-frame IoU on "
                       + ("recorded maps" if args.maps else
                          f"synthetic walks ({', '.join(per_seq)}), {args.frames} frames each, "
                          f"seed {args.seed}"),
        "profile": args.profile or "default",
        "map_cells": int(cells if not args.maps else -1),
        "resolution_m": float(resolution),
        "machine_load_1min_procs": float(figures_load),
    }
    for stage in (*STAGES, "total", "wall", "cpu", "mapping", "perception"):
        figures.update(summarize(merged[stage], stage))
    total = np.asarray(merged["wall"])
    figures["over_budget_33ms_ratio"] = float(np.mean(total > BUDGET_MS))
    figures["over_aim_10ms_ratio"] = float(np.mean(total > AIM_MS))
    if merged["perception"]:
        per = np.asarray(merged["perception"])
        figures["perception_over_budget_33ms_ratio"] = float(np.mean(per > BUDGET_MS))
    figures.update(_ratio_stats(merged["safe_iou"], "safe_iou"))
    figures.update(_ratio_stats(merged["decomposition_iou"], "decomposition_iou"))
    for key in ("polygons", "acd_cuts", "whittle_cuts", "dropped"):
        figures[f"{key}_median_count"] = float(np.median(merged[key]))
        figures[f"{key}_max_count"] = float(np.max(merged[key]))
    for name, res_seq in per_seq.items():
        figures.update(summarize(res_seq["wall"], f"{name}_wall"))
        figures.update(summarize(res_seq["cpu"], f"{name}_cpu"))
        figures.update(_ratio_stats(res_seq["safe_iou"], f"{name}_safe_iou"))
        figures.update(_ratio_stats(res_seq["decomposition_iou"], f"{name}_decomposition_iou"))

    rows = []
    for stage in (*STAGES, "total", "wall", "cpu", "mapping", "perception"):
        if not figures.get(f"{stage}_count"):
            continue
        rows.append((f"{stage} median / p99 / max [ms]",
                     f"{figures[f'{stage}_median_ms']:.2f} / {figures[f'{stage}_p99_ms']:.2f} / "
                     f"{figures[f'{stage}_max_ms']:.2f}"))
    rows.append(("S3 frames over 33 ms / over 10 ms",
                 f"{figures['over_budget_33ms_ratio']:.3f} / {figures['over_aim_10ms_ratio']:.3f}"))
    if "perception_over_budget_33ms_ratio" in figures:
        rows.append(("map + S3 frames over 33 ms",
                     f"{figures['perception_over_budget_33ms_ratio']:.3f}"))
    rows.append(("machine load average (1 min) at start", f"{figures_load:.2f}"))
    print_table("S3 per-stage time (all sequences)", rows)
    iou_rows = []
    for name in (*per_seq, None):
        pre = "" if name is None else f"{name}_"
        label = "all" if name is None else name
        for kind in ("safe_iou", "decomposition_iou"):
            key = f"{pre}{kind}"
            if figures.get(f"{key}_count", 0):
                iou_rows.append((f"{label} {kind} median / p5 / min",
                                 f"{figures[f'{key}_median_ratio']:.3f} / "
                                 f"{figures[f'{key}_p5_ratio']:.3f} / "
                                 f"{figures[f'{key}_min_ratio']:.3f}"))
    for key in ("polygons", "acd_cuts", "whittle_cuts", "dropped"):
        iou_rows.append((f"{key} per frame median / max",
                         f"{figures[f'{key}_median_count']:.0f} / "
                         f"{figures[f'{key}_max_count']:.0f}"))
    print_table("Frame-to-frame IoU (Section VIII-D)", iou_rows)
    write_json(args.json, "s3", figures)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
