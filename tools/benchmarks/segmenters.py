"""`cassie bench segmenters`: the paper's perception evaluation (Section VIII-D, Figs. 15-19)
on elevation maps recorded from closed-loop walking (``cassie experiment NAME --perception
--record-maps FILE.npz``).

Per terrain: S3 (+ convex decomposition), the plane-segmentation baselines EM_cupy and
EM_cupy_NR (``tools.segmentation_baselines``) and QuadPiPS' superpixel planar regions
(``processes.superpixels``) on the same maps: run time per map (wall and thread CPU) and
frame-to-frame IoU of the safe terrain on the cells both frames hold (Fig. 16); the IoU of the
polygons' coverage beside the safe terrain's, for S3 and the superpixels (Fig. 18), and their
polygon counts; the worst case of each stage of the perception stack, elevation mapping
included (Fig. 15); and S3's IoU for hysteresis k_hyst from 0 to 0.6 (Fig. 19). The
superpixels' safe terrain is the cells they may cluster (known, a healthy normal, steppable),
the set their polygons are drawn from, as S3's safe terrain is the set its decomposition
covers. ``--methods`` picks the methods; with S3 and the superpixels both, ``--plots`` also
draws them against each other (one frame of each terrain with both sets of polygons, run time
and IoU bars). Figures in a flat JSON, one PNG per figure.
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
from processes.superpixels import STAGES as SUPERPIXEL_STAGES
from processes.superpixels import SuperpixelParams, SuperpixelSegmenter
from runtime.geometry import Foothold
from runtime.params import load
from tools.benchmarks.common import print_table, progress, summarize, write_json
from tools.segmentation_baselines import segment

REPO = Path(__file__).resolve().parents[2]
S3_GAINS = REPO / "hw_config" / "gains" / "s3.yaml"
SUPERPIXELS_GAINS = REPO / "hw_config" / "gains" / "superpixels.yaml"
METHODS = ("S3", "EM_cupy", "EM_cupy_NR", "superpixels")
#: the methods that give polygons (the others only a safe mask)
POLYGON_METHODS = ("S3", "superpixels")
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


def _track(out: dict[str, list[float]], prev: tuple[np.ndarray, np.ndarray, np.ndarray] | None,
           safe: np.ndarray, footholds: list[Foothold], maps: MapSet, k: int
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Frame k's polygon count and its IoUs with the frame before (``prev``: its safe mask,
    polygon coverage and origin) of the safe terrain and of the polygons' coverage; returns
    frame k's for the next."""
    out["polygons"].append(float(len(footholds)))
    cover = coverage_mask([f.vertices_xy for f in footholds], safe.shape, maps.resolution,
                          maps.origin[k])
    if prev is not None:
        out["iou"].append(frame_iou(prev[0], prev[2], safe, maps.origin[k], maps.resolution))
        out["decomposition_iou"].append(frame_iou(prev[1], prev[2], cover, maps.origin[k],
                                                  maps.resolution))
    return safe, cover, np.asarray(maps.origin[k])


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
        prev = _track(out, prev, r.safe_mask, r.footholds, maps, k)
        bar.update(1)
    bar.close()
    return out


def run_superpixels(maps: MapSet, seg: SuperpixelSegmenter, desc: str
                    ) -> dict[str, list[float]]:
    """The superpixels over a terrain's maps: stage times, wall and CPU per map, polygon
    count, and the frame-to-frame IoU of the safe terrain (the cells they may cluster) and of
    the polygons' coverage. No memory between maps: each is segmented afresh."""
    out: dict[str, list[float]] = {k: [] for k in (*SUPERPIXEL_STAGES, "wall", "cpu",
                                                   "polygons", "iou", "decomposition_iou")}
    prev: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
    bar = progress(len(maps.elevation), desc, unit="map")
    for k in range(len(maps.elevation)):
        c0, t0 = time.thread_time(), time.perf_counter()
        r = seg.segment(maps.elevation[k], maps.resolution, maps.origin[k])
        out["wall"].append((time.perf_counter() - t0) * 1e3)
        out["cpu"].append((time.thread_time() - c0) * 1e3)
        for s in SUPERPIXEL_STAGES:
            out[s].append(r.times_ms.get(s, 0.0))
        prev = _track(out, prev, r.safe_mask, r.footholds, maps, k)
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


#: frame pairs left out of the "settled" minimum: the first second at 30 Hz, while the map
#: fills in from its first depth frames (a third of the cells known at frame 1, measured)
SETTLE_FRAMES = 30


def _iou_stats(a: list[float], prefix: str) -> dict[str, float]:
    """Median, p5 and min of frame-to-frame IoUs, and the min once the map has settled."""
    x = np.asarray(a, dtype=float)
    late = x[SETTLE_FRAMES - 1:]
    late = late[np.isfinite(late)]
    x = x[np.isfinite(x)]
    if x.size == 0:
        return {f"{prefix}_count": 0}
    out = {f"{prefix}_count": int(x.size), f"{prefix}_median_ratio": float(np.median(x)),
           f"{prefix}_p5_ratio": float(np.percentile(x, 5.0)),
           f"{prefix}_min_ratio": float(x.min())}
    if late.size:
        out[f"{prefix}_min_settled_ratio"] = float(late.min())
    return out


def _iou_cells(f: dict[str, Any], prefix: str) -> str:
    """'median / p5 / min (min after 1 s)' of ``_iou_stats``' figures under ``prefix``."""
    return (f"{f[f'{prefix}_median_ratio']:.3f} / {f[f'{prefix}_p5_ratio']:.3f} / "
            f"{f[f'{prefix}_min_ratio']:.3f} ({f.get(f'{prefix}_min_settled_ratio', np.nan):.3f})")


def _save(fig: Any, path: Path, paths: list[Path]) -> None:
    """Write a figure's PNG, close it and note its path."""
    import matplotlib.pyplot as plt

    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    paths.append(path)


def _plots(res: dict[str, dict[str, dict[str, list[float]]]], methods: list[str],
           hyst: dict[float, list[float]], mapping: dict[str, np.ndarray], hyst_terrain: str,
           out_dir: Path) -> list[Path]:
    """Figs. 15, 16, 18 and 19 as PNGs in ``out_dir`` (those the methods run give)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out_dir.mkdir(parents=True, exist_ok=True)
    terrains = list(res)
    paths: list[Path] = []
    if "S3" in methods:  # Fig. 15: worst case of each stage, per terrain
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
        _save(fig, out_dir / "fig15_stage_worst_case.png", paths)
    # Fig. 16: run time and IoU histograms, per terrain and method
    fig, axes = plt.subplots(2, len(terrains), figsize=(3.6 * len(terrains), 5.6),
                             squeeze=False)
    for j, t in enumerate(terrains):
        for m in methods:
            axes[0, j].hist(res[t][m]["wall"], bins=40, alpha=0.6, label=m)
            axes[1, j].hist(res[t][m]["iou"], bins=np.linspace(0, 1, 41), alpha=0.6, label=m)
        axes[0, j].set_title(t)
        axes[0, j].set_xlabel("run time per map [ms]")
        axes[1, j].set_xlabel("frame-to-frame IoU of the safe terrain")
        axes[1, j].set_yscale("log")
    axes[0, 0].legend()
    fig.suptitle(f"Fig. 16: {', '.join(methods)}")
    _save(fig, out_dir / "fig16_runtime_iou.png", paths)
    # Fig. 18: the safe terrain's IoU beside its polygons', for each method with polygons
    with_polygons = [m for m in POLYGON_METHODS if m in methods]
    if with_polygons:
        fig, axes = plt.subplots(1, len(with_polygons), figsize=(6.0 * len(with_polygons), 3.6),
                                 squeeze=False)
        for ax, m in zip(axes[0], with_polygons, strict=True):
            safe = [x for t in terrains for x in res[t][m]["iou"]]
            dec = [x for t in terrains for x in res[t][m]["decomposition_iou"]]
            ax.hist(safe, bins=np.linspace(0, 1, 41), alpha=0.6, label="safe terrain")
            ax.hist(dec, bins=np.linspace(0, 1, 41), alpha=0.6, label="polygons")
            ax.set_yscale("log")
            ax.set_xlabel("frame-to-frame IoU")
            ax.set_title(f"Fig. 18: {m}, safe terrain vs its polygons (all terrains)")
            ax.legend()
        _save(fig, out_dir / "fig18_decomposition_iou.png", paths)
    if hyst:  # Fig. 19: IoU against hysteresis
        fig, ax = plt.subplots(figsize=(6.0, 3.6))
        ks = sorted(hyst)
        ax.boxplot([hyst[k] for k in ks], tick_labels=[f"{k:g}" for k in ks], whis=(0, 100))
        ax.set_xlabel("k_hyst")
        ax.set_ylabel("frame-to-frame IoU")
        ax.set_title(f"Fig. 19: S3 IoU against hysteresis ({hyst_terrain})")
        _save(fig, out_dir / "fig19_hysteresis_iou.png", paths)
    return paths


def _comparison_plots(sets: list[MapSet], res: dict[str, dict[str, dict[str, list[float]]]],
                      s3_params: S3Params, seg: SuperpixelSegmenter, out_dir: Path
                      ) -> list[Path]:
    """S3 against the superpixels: the middle frame of each terrain with both segmenters'
    safe terrain and polygons over the elevation map; run time and IoU bars per terrain."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out_dir.mkdir(parents=True, exist_ok=True)
    paths: list[Path] = []
    fig, axes = plt.subplots(2, len(sets), figsize=(3.4 * len(sets), 6.8), squeeze=False)
    for j, ms in enumerate(sets):
        k = len(ms.elevation) // 2
        e, o, r = ms.elevation[k], np.asarray(ms.origin[k]), ms.resolution
        low = None if ms.lowest is None else ms.lowest[k]
        s3 = S3Pipeline(s3_params).process(e, r, o, lowest=low)  # no hysteresis: one frame
        sp = seg.segment(e, r, o)
        extent = (o[0] - r / 2, o[0] + r * (e.shape[1] - 0.5),
                  o[1] - r / 2, o[1] + r * (e.shape[0] - 0.5))
        for ax, name, mask, fhs in ((axes[0, j], "superpixels", sp.safe_mask, sp.footholds),
                                    (axes[1, j], "S3", s3.safe_mask, s3.footholds)):
            ax.imshow(e, origin="lower", extent=extent, cmap="viridis")
            ax.contour(mask, [0.5], colors="w", linewidths=0.6, extent=extent,
                       origin="lower")
            for f in fhs:
                v = np.vstack((f.vertices_xy, f.vertices_xy[:1]))
                ax.plot(v[:, 0], v[:, 1], "r-", lw=1.0)
            ax.set_title(f"{ms.name} frame {k}: {name}, {len(fhs)} polygons", fontsize=8)
            ax.set_xticks([])
            ax.set_yticks([])
    fig.suptitle("Elevation (colour, NaN white), safe terrain (white line), polygons (red)")
    _save(fig, out_dir / "frames.png", paths)
    names = [ms.name for ms in sets]
    x = np.arange(len(names))
    fig, axes = plt.subplots(1, 2, figsize=(12.0, 3.8))
    for i, m in enumerate(("S3", "superpixels")):
        for ax, key in zip(axes, ("wall", "cpu"), strict=True):
            vals = [np.asarray(res[t][m][key]) for t in names]
            med = [float(np.median(v)) for v in vals]
            p99 = [float(np.percentile(v, 99.0)) for v in vals]
            top = [float(v.max()) for v in vals]
            ax.bar(x + (i - 0.5) * 0.4, med, 0.4, label=f"{m} median", color=f"C{i}")
            ax.scatter(x + (i - 0.5) * 0.4, p99, marker="_", s=200, color="k",
                       label="p99" if i == 0 else None)
            ax.scatter(x + (i - 0.5) * 0.4, top, marker="v", color=f"C{i}",
                       label=f"{m} max")
            ax.axhline(33.0, color="r", lw=0.8, ls="--")
            ax.set_xticks(x, names, rotation=20)
            ax.set_ylabel(f"{key} time per map [ms]")
            ax.set_title(f"{key} time per map (red: one camera frame, 33 ms)")
    axes[0].legend(fontsize=7)
    _save(fig, out_dir / "runtime.png", paths)
    fig, axes = plt.subplots(1, 2, figsize=(12.0, 3.8))
    for ax, key, what in zip(axes, ("iou", "decomposition_iou"), ("safe terrain", "polygons"),
                             strict=True):
        for i, m in enumerate(("S3", "superpixels")):
            vals = [np.asarray(res[t][m][key], dtype=float) for t in names]
            vals = [v[np.isfinite(v)] for v in vals]
            ax.bar(x + (i - 0.5) * 0.4, [float(np.median(v)) for v in vals], 0.4,
                   label=f"{m} median", color=f"C{i}")
            ax.scatter(x + (i - 0.5) * 0.4, [float(v.min()) for v in vals], marker="v",
                       color="k", label="min" if i == 0 else None)
        ax.set_ylim(0.0, 1.02)
        ax.set_xticks(x, names, rotation=20)
        ax.set_ylabel("frame-to-frame IoU")
        ax.set_title(f"IoU of the {what}")
    axes[0].legend(fontsize=7, loc="lower left")
    _save(fig, out_dir / "iou.png", paths)
    return paths


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="cassie bench segmenters",
                                 description=__doc__.splitlines()[0])
    ap.add_argument("--maps", nargs="+", required=True, metavar="NAME=FILE.npz",
                    help="recorded maps per terrain (cassie experiment ... --record-maps)")
    ap.add_argument("--frames", type=int, default=0, help="maps per terrain (0: all)")
    ap.add_argument("--methods", default=",".join(METHODS),
                    help=f"comma-separated, of {', '.join(METHODS)} (default: all)")
    ap.add_argument("--hysteresis", default=",".join(f"{k:g}" for k in HYSTERESIS),
                    help="k_hyst values for Fig. 19 (comma-separated; empty: no Fig. 19)")
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
    methods = [m.strip() for m in args.methods.split(",") if m.strip()]
    if not methods or any(m not in METHODS for m in methods):
        ap.error(f"--methods {args.methods!r}: some of {', '.join(METHODS)}")
    try:
        ks = [float(x) for x in args.hysteresis.split(",") if x.strip()]
    except ValueError:
        ap.error(f"--hysteresis {args.hysteresis!r}: want numbers, e.g. 0,0.2,0.4")
    if "S3" not in methods:
        ks = []
    hyst_name = args.hysteresis_terrain or sets[-1].name
    if hyst_name not in {s.name for s in sets}:
        ap.error(f"--hysteresis-terrain {hyst_name!r} is not one of the --maps names")
    params = load(S3Params, S3_GAINS, args.variant)
    sp_params = load(SuperpixelParams, SUPERPIXELS_GAINS)
    seg = SuperpixelSegmenter(sp_params) if "superpixels" in methods else None

    gc.collect()
    gc.freeze()
    load_avg = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    res: dict[str, dict[str, dict[str, list[float]]]] = {}
    for s in sets:
        res[s.name] = {}
        for m in methods:
            desc = f"{s.name} {m}"
            if m == "S3":
                res[s.name][m] = run_s3(s, params, desc)
            elif m == "superpixels":
                assert seg is not None
                res[s.name][m] = run_superpixels(s, seg, desc)
            else:
                res[s.name][m] = run_baseline(s, m == "EM_cupy", desc)
    hyst: dict[float, list[float]] = {}
    hs = next(s for s in sets if s.name == hyst_name)
    for k in ks:
        p = dataclasses.replace(params, k_hyst=k)
        hyst[k] = run_s3(hs, p, f"{hyst_name} k_hyst {k:g}")["iou"]

    figures: dict[str, Any] = {
        "description": f"{', '.join(methods)} on recorded elevation maps "
                       f"({', '.join(f'{s.name}: {len(s.elevation)} maps' for s in sets)}); "
                       f"S3 {args.variant} gains (k_hyst {params.k_hyst:g}), superpixels "
                       f"gains/superpixels.yaml (k_des {sp_params.k_des}, n_iter "
                       f"{sp_params.n_iter})",
        "machine_load_1min_procs": float(load_avg),
    }
    rows, iou_rows, poly_rows = [], [], []
    for s in sets:
        t = s.name
        figures.update(summarize(s.mapping_ms[np.isfinite(s.mapping_ms)], f"{t}_mapping"))
        for m in methods:
            figures.update(summarize(res[t][m]["wall"], f"{t}_{m}_wall"))
            figures.update(summarize(res[t][m]["cpu"], f"{t}_{m}_cpu"))
            figures.update(_iou_stats(res[t][m]["iou"], f"{t}_{m}_iou"))
            f = figures
            rows.append((f"{t} {m} wall median / p99 / max [ms] (cpu median / max)",
                         f"{f[f'{t}_{m}_wall_median_ms']:.2f} / {f[f'{t}_{m}_wall_p99_ms']:.2f} "
                         f"/ {f[f'{t}_{m}_wall_max_ms']:.2f} ({f[f'{t}_{m}_cpu_median_ms']:.2f}"
                         f" / {f[f'{t}_{m}_cpu_max_ms']:.2f})"))
            iou_rows.append((f"{t} {m} IoU median / p5 / min (after 1 s)",
                             _iou_cells(f, f"{t}_{m}_iou")))
            if m not in POLYGON_METHODS:
                continue
            figures.update(_iou_stats(res[t][m]["decomposition_iou"],
                                      f"{t}_{m}_decomposition_iou"))
            polys = np.asarray(res[t][m]["polygons"])
            figures[f"{t}_{m}_polygons_median_count"] = float(np.median(polys))
            figures[f"{t}_{m}_polygons_max_count"] = float(polys.max())
            iou_rows.append((f"{t} {m} polygons IoU median / p5 / min (after 1 s)",
                             _iou_cells(f, f"{t}_{m}_decomposition_iou")))
            poly_rows.append((f"{t} {m} polygons median / max",
                              f"{np.median(polys):.0f} / {polys.max():.0f}"))
            stages = STAGES if m == "S3" else SUPERPIXEL_STAGES
            for st in stages:
                figures[f"{t}_{m}_{st}_max_ms"] = float(max(res[t][m][st]))
                figures[f"{t}_{m}_{st}_median_ms"] = float(np.median(res[t][m][st]))
        if "S3" in methods:
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
    print_table("Frame-to-frame IoU (Figs. 16 bottom, 18, 19)", iou_rows)
    if poly_rows:
        print_table("Polygons per map", poly_rows)
    if args.plots:
        mapping = {s.name: s.mapping_ms for s in sets}
        paths = _plots(res, methods, hyst, mapping, hyst_name, args.plots)
        if seg is not None and "S3" in methods:
            paths += _comparison_plots(sets, res, params, seg, args.plots)
        for p in paths:
            print(f"wrote {p}")
    write_json(args.json, "segmenters", figures)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
