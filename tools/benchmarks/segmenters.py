"""`cassie bench segmenters`: the paper's perception evaluation (Section VIII-D, Figs. 15-19)
on elevation maps recorded from closed-loop walking (``cassie experiment NAME --perception
--record-maps FILE.npz``).

Per terrain: S3 (+ convex decomposition) and the plane-segmentation baselines EM_cupy and
EM_cupy_NR (``tools.segmentation_baselines``) on the same maps: run time per map (wall and
thread CPU) and frame-to-frame IoU of the safe terrain on the cells both frames hold (Fig. 16);
the IoU of the convex decomposition's coverage beside S3's safe terrain (Fig. 18); the worst
case of each stage of the perception stack, elevation mapping included (Fig. 15); and S3's
IoU for hysteresis k_hyst from 0 to 0.6 (Fig. 19). Figures in a flat JSON, one PNG per figure.
"""

from __future__ import annotations

import argparse
import dataclasses
import gc
import os
import time
from pathlib import Path
from typing import Any

import numpy as np

from processes.s3 import STAGES, S3Params, S3Pipeline
from processes.s3.metrics import coverage_mask, frame_iou
from runtime.params import load
from tools.benchmarks.common import print_table, progress, summarize, write_json
from tools.segmentation_baselines import segment

REPO = Path(__file__).resolve().parents[2]
S3_GAINS = REPO / "hw_config" / "gains" / "s3.yaml"
METHODS = ("S3", "EM_cupy", "EM_cupy_NR")
HYSTERESIS = (0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6)


@dataclasses.dataclass
class MapSet:
    """The recorded maps of one terrain."""

    name: str
    elevation: np.ndarray  # (F, R, C)
    lowest: np.ndarray | None
    origin: np.ndarray  # (F, 2)
    resolution: float
    mapping_ms: np.ndarray  # (F,) the perception tick that made each map (nan: unknown)

    @classmethod
    def load(cls, name: str, path: Path, frames: int = 0) -> MapSet:
        d = np.load(path)
        n = len(d["elevation"]) if frames <= 0 else min(frames, len(d["elevation"]))
        low = d["lowest"][:n] if "lowest" in d else None
        mapping = d["mapping_ms"][:n] if "mapping_ms" in d else np.full(n, np.nan)
        return cls(name, d["elevation"][:n], low, d["origin"][:n], float(d["resolution"]),
                   mapping)


def run_s3(maps: MapSet, params: S3Params, desc: str) -> dict[str, list[float]]:
    """S3 and the decomposition over a terrain's maps: stage times, wall and CPU per map,
    polygon count, and the frame-to-frame IoU of the safe terrain and of the coverage."""
    pipe = S3Pipeline(params)
    out: dict[str, list[float]] = {k: [] for k in (*STAGES, "wall", "cpu", "polygons",
                                                   "iou", "decomposition_iou")}
    prev: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
    bar = progress(len(maps.elevation), desc, unit="map")
    for k in range(len(maps.elevation)):
        low = None if maps.lowest is None else maps.lowest[k]
        c0, t0 = time.thread_time(), time.perf_counter()
        r = pipe.process(maps.elevation[k], maps.resolution, maps.origin[k], lowest=low)
        out["wall"].append((time.perf_counter() - t0) * 1e3)
        out["cpu"].append((time.thread_time() - c0) * 1e3)
        for s in STAGES:
            out[s].append(r.times_ms.get(s, 0.0))
        out["polygons"].append(float(len(r.footholds)))
        cover = coverage_mask([f.vertices_xy for f in r.footholds], r.safe_mask.shape,
                              maps.resolution, maps.origin[k])
        if prev is not None:
            out["iou"].append(frame_iou(prev[0], prev[2], r.safe_mask, maps.origin[k],
                                        maps.resolution))
            out["decomposition_iou"].append(frame_iou(prev[1], prev[2], cover, maps.origin[k],
                                                      maps.resolution))
        prev = (r.safe_mask, cover, np.asarray(maps.origin[k]))
        bar.update(1)
    bar.close()
    return out


def run_baseline(maps: MapSet, refine: bool, desc: str) -> dict[str, list[float]]:
    """EM_cupy (``refine``) or EM_cupy_NR over a terrain's maps: wall and CPU time per map and
    the frame-to-frame IoU of the safe terrain. RANSAC is seeded by the frame's index."""
    out: dict[str, list[float]] = {"wall": [], "cpu": [], "iou": [], "planes": []}
    prev: tuple[np.ndarray, np.ndarray] | None = None
    bar = progress(len(maps.elevation), desc, unit="map")
    for k in range(len(maps.elevation)):
        c0, t0 = time.thread_time(), time.perf_counter()
        r = segment(maps.elevation[k], maps.resolution, refine=refine, seed=k)
        out["wall"].append((time.perf_counter() - t0) * 1e3)
        out["cpu"].append((time.thread_time() - c0) * 1e3)
        out["planes"].append(float(r.planes))
        if prev is not None:
            out["iou"].append(frame_iou(prev[0], prev[1], r.safe_mask, maps.origin[k],
                                        maps.resolution))
        prev = (r.safe_mask, np.asarray(maps.origin[k]))
        bar.update(1)
    bar.close()
    return out


def _iou_stats(a: list[float], prefix: str) -> dict[str, float]:
    x = np.asarray(a, dtype=float)
    x = x[np.isfinite(x)]
    if x.size == 0:
        return {f"{prefix}_count": 0}
    return {f"{prefix}_count": int(x.size), f"{prefix}_median_ratio": float(np.median(x)),
            f"{prefix}_p5_ratio": float(np.percentile(x, 5.0)),
            f"{prefix}_min_ratio": float(x.min())}


def _plots(res: dict[str, dict[str, dict[str, list[float]]]], hyst: dict[float, list[float]],
           mapping: dict[str, np.ndarray], hyst_terrain: str, out_dir: Path) -> list[Path]:
    """Figs. 15, 16, 18 and 19 as PNGs in ``out_dir``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out_dir.mkdir(parents=True, exist_ok=True)
    terrains = list(res)
    paths = []
    # Fig. 15: worst case of each stage, per terrain
    fig, ax = plt.subplots(figsize=(7.5, 3.8))
    stages = ("mapping", *STAGES)
    width = 0.8 / len(terrains)
    for i, t in enumerate(terrains):
        worst = [float(np.nanmax(mapping[t])) if np.isfinite(mapping[t]).any() else 0.0]
        worst += [max(res[t]["S3"][s]) for s in STAGES]
        ax.bar(np.arange(len(stages)) + i * width, worst, width, label=t)
    ax.set_xticks(np.arange(len(stages)) + 0.4 - width / 2, stages, rotation=20)
    ax.set_ylabel("worst case [ms]")
    ax.set_title("Fig. 15: worst-case time of each perception stage")
    ax.legend()
    fig.tight_layout()
    paths.append(out_dir / "fig15_stage_worst_case.png")
    fig.savefig(paths[-1], dpi=110)
    plt.close(fig)
    # Fig. 16: run time and IoU histograms, per terrain and method
    fig, axes = plt.subplots(2, len(terrains), figsize=(3.6 * len(terrains), 5.6),
                             squeeze=False)
    for j, t in enumerate(terrains):
        for m in METHODS:
            axes[0, j].hist(res[t][m]["wall"], bins=40, alpha=0.6, label=m)
            axes[1, j].hist(res[t][m]["iou"], bins=np.linspace(0, 1, 41), alpha=0.6, label=m)
        axes[0, j].set_title(t)
        axes[0, j].set_xlabel("run time per map [ms]")
        axes[1, j].set_xlabel("frame-to-frame IoU of the safe terrain")
        axes[1, j].set_yscale("log")
    axes[0, 0].legend()
    fig.suptitle("Fig. 16: S3 against plane segmentation")
    fig.tight_layout()
    paths.append(out_dir / "fig16_runtime_iou.png")
    fig.savefig(paths[-1], dpi=110)
    plt.close(fig)
    # Fig. 18: S3's safe terrain IoU beside its convex decomposition's
    fig, ax = plt.subplots(figsize=(6.0, 3.6))
    safe = [x for t in terrains for x in res[t]["S3"]["iou"]]
    dec = [x for t in terrains for x in res[t]["S3"]["decomposition_iou"]]
    ax.hist(safe, bins=np.linspace(0, 1, 41), alpha=0.6, label="safe terrain")
    ax.hist(dec, bins=np.linspace(0, 1, 41), alpha=0.6, label="convex decomposition")
    ax.set_yscale("log")
    ax.set_xlabel("frame-to-frame IoU")
    ax.set_title("Fig. 18: S3 safe terrain vs its convex decomposition (all terrains)")
    ax.legend()
    fig.tight_layout()
    paths.append(out_dir / "fig18_decomposition_iou.png")
    fig.savefig(paths[-1], dpi=110)
    plt.close(fig)
    # Fig. 19: IoU against hysteresis
    fig, ax = plt.subplots(figsize=(6.0, 3.6))
    ks = sorted(hyst)
    ax.boxplot([hyst[k] for k in ks], tick_labels=[f"{k:g}" for k in ks], whis=(0, 100))
    ax.set_xlabel("k_hyst")
    ax.set_ylabel("frame-to-frame IoU")
    ax.set_title(f"Fig. 19: S3 IoU against hysteresis ({hyst_terrain})")
    fig.tight_layout()
    paths.append(out_dir / "fig19_hysteresis_iou.png")
    fig.savefig(paths[-1], dpi=110)
    plt.close(fig)
    return paths


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="cassie bench segmenters",
                                 description=__doc__.splitlines()[0])
    ap.add_argument("--maps", nargs="+", required=True, metavar="NAME=FILE.npz",
                    help="recorded maps per terrain (cassie experiment ... --record-maps)")
    ap.add_argument("--frames", type=int, default=0, help="maps per terrain (0: all)")
    ap.add_argument("--hysteresis", default=",".join(f"{k:g}" for k in HYSTERESIS),
                    help="k_hyst values for Fig. 19 (comma-separated)")
    ap.add_argument("--hysteresis-terrain", default=None,
                    help="the terrain of Fig. 19 (default: the last of --maps)")
    ap.add_argument("--variant", default="simulation", help="S3 gains variant (Table VIII)")
    ap.add_argument("--plots", type=Path, default=None, help="write the figures' PNGs here")
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args(argv)
    sets = []
    for spec in args.maps:
        name, sep, path = spec.partition("=")
        if not sep or not Path(path).is_file():
            ap.error(f"--maps {spec!r}: want NAME=FILE.npz with an existing file")
        sets.append(MapSet.load(name, Path(path), args.frames))
    try:
        ks = [float(x) for x in args.hysteresis.split(",") if x.strip()]
    except ValueError:
        ap.error(f"--hysteresis {args.hysteresis!r}: want numbers, e.g. 0,0.2,0.4")
    hyst_name = args.hysteresis_terrain or sets[-1].name
    if hyst_name not in {s.name for s in sets}:
        ap.error(f"--hysteresis-terrain {hyst_name!r} is not one of the --maps names")
    params = load(S3Params, S3_GAINS, args.variant)

    gc.collect()
    gc.freeze()
    load_avg = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    res: dict[str, dict[str, dict[str, list[float]]]] = {}
    for s in sets:
        res[s.name] = {
            "S3": run_s3(s, params, f"{s.name} S3"),
            "EM_cupy": run_baseline(s, True, f"{s.name} EM_cupy"),
            "EM_cupy_NR": run_baseline(s, False, f"{s.name} EM_cupy_NR"),
        }
    hyst: dict[float, list[float]] = {}
    hs = next(s for s in sets if s.name == hyst_name)
    for k in ks:
        p = dataclasses.replace(params, k_hyst=k)
        hyst[k] = run_s3(hs, p, f"{hyst_name} k_hyst {k:g}")["iou"]

    figures: dict[str, Any] = {
        "description": "S3 vs plane segmentation on recorded elevation maps "
                       f"({', '.join(f'{s.name}: {len(s.elevation)} maps' for s in sets)}); "
                       f"S3 {args.variant} gains (k_hyst {params.k_hyst:g})",
        "machine_load_1min_procs": float(load_avg),
    }
    rows, iou_rows = [], []
    for s in sets:
        t = s.name
        figures.update(summarize(s.mapping_ms[np.isfinite(s.mapping_ms)], f"{t}_mapping"))
        for m in METHODS:
            figures.update(summarize(res[t][m]["wall"], f"{t}_{m}_wall"))
            figures.update(summarize(res[t][m]["cpu"], f"{t}_{m}_cpu"))
            figures.update(_iou_stats(res[t][m]["iou"], f"{t}_{m}_iou"))
            f = figures
            rows.append((f"{t} {m} wall median / p99 / max [ms] (cpu median)",
                         f"{f[f'{t}_{m}_wall_median_ms']:.2f} / {f[f'{t}_{m}_wall_p99_ms']:.2f} "
                         f"/ {f[f'{t}_{m}_wall_max_ms']:.2f} ({f[f'{t}_{m}_cpu_median_ms']:.2f})"))
            iou_rows.append((f"{t} {m} IoU median / p5 / min",
                             f"{f[f'{t}_{m}_iou_median_ratio']:.3f} / "
                             f"{f[f'{t}_{m}_iou_p5_ratio']:.3f} / "
                             f"{f[f'{t}_{m}_iou_min_ratio']:.3f}"))
        figures.update(_iou_stats(res[t]["S3"]["decomposition_iou"], f"{t}_S3_decomposition_iou"))
        for st in STAGES:
            figures[f"{t}_S3_{st}_max_ms"] = float(max(res[t]["S3"][st]))
        figures[f"{t}_S3_polygons_max_count"] = float(max(res[t]["S3"]["polygons"]))
        worst = (np.nanmax(s.mapping_ms) if np.isfinite(s.mapping_ms).any() else 0.0) + \
            max(res[t]["S3"]["wall"])
        figures[f"{t}_perception_worst_sum_ms"] = float(worst)
    for k in ks:
        figures.update(_iou_stats(hyst[k], f"hysteresis_{k:g}_iou".replace(".", "p")))
        iou_rows.append((f"{hyst_name} S3 k_hyst {k:g} IoU median / p5 / min",
                         "{:.3f} / {:.3f} / {:.3f}".format(
                             *(figures[f"hysteresis_{k:g}_iou_{q}_ratio".replace(".", "p", 1)]
                               for q in ("median", "p5", "min")))))
    print_table("Run time per map (Fig. 16 top)", rows)
    print_table("Frame-to-frame IoU (Figs. 16 bottom, 19)", iou_rows)
    if args.plots:
        mapping = {s.name: s.mapping_ms for s in sets}
        for p in _plots(res, hyst, mapping, hyst_name, args.plots):
            print(f"wrote {p}")
    write_json(args.json, "segmenters", figures)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
