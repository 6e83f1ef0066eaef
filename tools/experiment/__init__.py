"""`cassie experiment NAME`: a closed-loop walking experiment in the deterministic harness.

The same process nodes as `cassie launch` (from ``hw_config/experiment.yaml``) are stepped in
sim-time order inside this one process, so a result depends on the seed and the code, never on
how busy the machine is. Terrains: ``flat``, ``stairs`` (15 cm rise, 27 cm depth; 40 cm with
``--perception``, as the paper's Fig. 11), ``beam``
(23 cm wide), ``stones`` (the paper's random stepping stones, Table I, ``--dmin D``),
QuadPiPS' ``ramped_stones`` (those stones with tops tilted up to 10 deg) and ``winding_beam``
(23 cm wide, segments turning 20-30 deg; the operator steers along its centre line), and
``chasm`` (a gap across the path between two platforms, ``--width W``, default 0.35 m), with
ground-truth footholds from the sim, or with ``--perception`` the footholds of S3; with
``--guide`` the SLIP guide (Bartlett & Manchester) runs beside the MPFC and guides it.

Reported per trial, from the sim's ground truth: distance walked, mean forward speed (from 1 s
after the release) against the command, falls (pelvis below 0.6 m over the terrain under it),
footsteps (touchdowns) and footsteps outside every foothold, whether the robot reached the
course's end, and whether the trial succeeded (``tools.experiment.judge``: on a course with an
end, reaching it without a fall and with no footstep outside a foothold; on flat ground, no
fall, speed within 15% of the command and no footstep outside).
"""

from __future__ import annotations

import argparse
import os
import sys
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np

from runtime.config import HW_CONFIG_DIR
from tools.benchmarks.common import print_table, write_json
from tools.experiment.courses import (
    PERCEPTION_BEAM_WIDTH_M,
    PERCEPTION_STAIRS_DEPTH_M,
    PLANNERS,
    SEGMENTERS,
    _terrain_file,
)
from tools.experiment.judge import Judge, Trial
from tools.experiment.operator import LATERAL_GAIN, LATERAL_MAX_MPS
from tools.experiment.trials import run_live_trial, run_trial
from tools.report import print_cpu, print_loops, print_realtime

EXPERIMENTS = ("flat", "stairs", "beam", "stones", "blocks", "ramped_stones", "winding_beam",
               "chasm", "cubes")
#: the experiments of a beam (``--width``, as the chasm's gap) and of Table I's stones
#: (``--dmin``)
BEAMS = ("beam", "winding_beam")
STONES = ("stones", "ramped_stones")
#: what ``--sweep`` may sweep on each experiment
SWEEPS = {"stones": "dmin", "ramped_stones": "dmin", "stairs": "depth", "beam": "width",
          "winding_beam": "width", "chasm": "width"}

__all__ = ["EXPERIMENTS", "PERCEPTION_BEAM_WIDTH_M", "PERCEPTION_STAIRS_DEPTH_M", "Judge",
           "Trial", "_terrain_file", "main", "run_live_trial", "run_trial"]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="cassie experiment",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    ap.add_argument("name", choices=EXPERIMENTS)
    ap.add_argument("--duration", type=float, default=10.0, help="sim seconds per trial")
    ap.add_argument("--seed", type=int, default=0,
                    help="terrain seed (stones, ramped_stones, winding_beam)")
    ap.add_argument("--trials", type=int, default=1, help="trials, seeds seed..seed+N-1")
    ap.add_argument("--dmin", type=float, default=None,
                    help="stones, ramped_stones: minimum side d_min, m")
    ap.add_argument("--depth", type=float, default=None,
                    help="stairs: tread depth, m (default 0.27 with true footholds and 0.40 "
                    "with --perception: the paper's Fig. 11, top and bottom)")
    ap.add_argument("--width", type=float, default=None,
                    help="beam, winding_beam: its width, m (default 0.23 with true footholds "
                    "and 0.35 with --perception: the paper's Fig. 11, top and bottom); chasm: "
                    "the gap's width across the path, m (default 0.35: "
                    "hw_config/terrains/chasm.yaml)")
    ap.add_argument("--guide", action="store_true",
                    help="the SLIP guide (Bartlett & Manchester's long-horizon planner, "
                         "processes/slip_guide) runs too, and the MPFC follows its plan: "
                         "footholds narrowed to its next regions, its CoM velocity as the "
                         "nominal step")
    ap.add_argument("--perception", action="store_true", help="S3 footholds, not ground truth")
    ap.add_argument("--fixed-timing", action="store_true",
                    help="the MPFC's step-timing optimisation off: t_min = t_max = T_ss (the "
                         "paper's Fixed-T; default Opt-T)")
    ap.add_argument("--planner", choices=PLANNERS, default="mpfc",
                    help="the footstep planner: mpfc (Acosta & Posa), dcm (Xiang et al.'s "
                         "variable-timing DCM MIQP), or its ablations dcm-B (fixed step), "
                         "dcm-C (N = 2), dcm-D (no viability constraints)")
    ap.add_argument("--segmenter", choices=SEGMENTERS, default="s3",
                    help="with --perception, the footholds from the elevation map: s3 (S3 + "
                         "convex decomposition), contours (the DCM planner's front end, "
                         "Xiang et al. Alg. 3) or superpixels (QuadPiPS' superpixel planar "
                         "regions, Asselmeier et al. V-D/E)")
    ap.add_argument("--true-state", action="store_true",
                    help="the controllers on the sim's true pose and velocity instead of the "
                         "estimator's (the paper's GT runs: ground-truth state and terrain)")
    ap.add_argument("--record-maps", type=Path, default=None, metavar="FILE.npz",
                    help="with --perception, in the harness: keep every elevation map of the "
                         "trial (and its mapping time) for `cassie bench segmenters`")
    ap.add_argument("--vx", type=float, default=0.375, help="commanded speed, m/s")
    ap.add_argument("--lateral-gain", type=float, default=LATERAL_GAIN, metavar="K",
                    help="the operator steers back onto the course's centre line at K m/s per "
                         f"metre off it, at most {LATERAL_MAX_MPS} m/s (default %(default)s)")
    ap.add_argument("--profile", type=Path, default=HW_CONFIG_DIR / "experiment.yaml")
    ap.add_argument("--json", type=Path, default=None)
    ap.add_argument(
        "--launch",
        choices=("lockstep", "realtime"),
        default=None,
        help="run the real multi-process stack (cassie launch of hw_config/sim.yaml) in this "
        "mode instead of the deterministic harness; prints the loops' timing from its log",
    )
    ap.add_argument("--log-dir", type=Path, default=None,
                    help="--launch: keep the LCM log and process logs here")
    ap.add_argument("--dashboard", action="store_true",
                    help="--launch: with the Rerun dashboard recording too (its CPU is in the "
                         "report's CPU table)")
    ap.add_argument("--sweep", default=None, metavar="dmin=LO:HI:STEP",
                    help="a sweep: every value of the parameter (stones, ramped_stones: dmin; "
                         "stairs: depth; beam, winding_beam, chasm: width; "
                         "A:B:STEP or A,B,C) times --trials seeds, as jobs over the cores; "
                         "resumable (finished trials are kept in OUT/trials.jsonl); writes "
                         "OUT/summary.json and OUT/summary.png (tools/experiment/sweep.py)")
    ap.add_argument("--out", type=Path, default=None, help="--sweep: its folder")
    ap.add_argument("--jobs", type=int, default=None,
                    help="--sweep: trials at once (default: one per core)")
    ap.add_argument("--hysteresis", default=None, metavar="K[,K...]",
                    help="cubes: S3's k_hyst of each trial (default 0,0.1,...,0.6: Table IV)")
    ap.add_argument("--stand", action="store_true",
                    help="cubes: the robot stands (the radio's stand switch) instead of walking")
    ap.add_argument("--cubes", type=int, default=3, help="cubes: cubes dropped per trial")
    ap.add_argument("--obstacle-variance", type=float, default=None, metavar="M2",
                    help="cubes: the elevation map's obstacle_variance_m2 (default: its gains "
                         "file's; 0: the map of Fankhauser et al. without it)")
    args = ap.parse_args(argv)
    if args.name == "cubes":
        return _cubes(ap, args)
    if args.sweep is not None:
        return _sweep(ap, args)
    if args.dmin is not None and args.name not in STONES:
        ap.error("--dmin is for the stones and ramped_stones experiments")
    if args.depth is not None and (args.name != "stairs" or not 0.1 <= args.depth <= 2.0):
        ap.error("--depth is for the stairs experiment, 0.1 to 2.0 m")
    if args.width is not None and (args.name not in (*BEAMS, "chasm")
                                   or not 0.05 <= args.width <= 2.0):
        ap.error("--width is for the beam, winding_beam and chasm experiments, 0.05 to 2.0 m")
    if args.duration <= 0 or args.trials < 1:
        ap.error("--duration must be > 0 and --trials >= 1")
    if args.name == "stairs" and args.perception and args.depth is None:
        # S3's safety margins leave no steppable band on 27 cm treads; the paper's perceptive
        # stairs are 40 cm deep (Section VIII-A, Fig. 11 bottom)
        args.depth = PERCEPTION_STAIRS_DEPTH_M
        print(f"stairs with perception: {args.depth:.2f} m treads, as the paper's Fig. 11 "
              "(--depth to change)")
    if args.name in BEAMS and args.perception and args.width is None:
        args.width = PERCEPTION_BEAM_WIDTH_M  # (as the stairs: the paper's Fig. 11, bottom)
        print(f"{args.name} with perception: {args.width:.2f} m wide, as the paper's Fig. 11 "
              "(--width to change)")
    size = args.depth if args.name == "stairs" else args.width
    recorder = None
    if args.record_maps is not None:
        if not args.perception or args.launch or args.trials != 1:
            ap.error("--record-maps records one harness trial with --perception")
        from tools.experiment.maps import MapRecorder

        recorder = MapRecorder()
    if args.launch:
        base = args.profile if args.profile != HW_CONFIG_DIR / "experiment.yaml" else (
            HW_CONFIG_DIR / "sim.yaml")
        trials = [
            run_live_trial(args.name, args.duration, args.seed + i, args.dmin, args.perception,
                           args.vx, args.launch, base,
                           args.log_dir / f"trial{i}" if args.log_dir else None, size,
                           args.dashboard, args.fixed_timing, args.lateral_gain,
                           args.true_state, args.planner, args.segmenter, args.guide)
            for i in range(args.trials)
        ]
    else:
        trials = [
            run_trial(args.name, args.duration, args.seed + i, args.dmin, args.perception,
                      args.vx, args.profile, setup=recorder, size=size,
                      fixed_timing=args.fixed_timing, lateral_gain=args.lateral_gain,
                      true_state=args.true_state, planner=args.planner,
                      segmenter=args.segmenter, guide=args.guide)
            for i in range(args.trials)
        ]
    if recorder is not None:
        n = recorder.save(args.record_maps)
        print(f"{n} elevation maps recorded in {args.record_maps}")
    for tr in trials:
        rows = {k: v for k, v in asdict(tr).items()
                if k not in ("notes", "timing", "cpu", "realtime")}
        print_table(f"experiment {tr.experiment}, seed {tr.seed}", rows)
        if tr.timing:  # the live run's loops, as `cassie report` prints them from its log
            print_loops(tr.timing)
            print_cpu(tr.cpu)
            print_realtime(tr.realtime)
        for note in tr.notes:
            print(f"  note: {note}")
    ok = sum(t.success for t in trials)
    figures: dict[str, Any] = {
        "description": f"{args.name} in the deterministic harness"
        + (" with perception" if args.perception else " with true footholds")
        + (", the sim's true state" if args.true_state else ", the estimator's state")
        + (", Fixed-T" if args.fixed_timing else "")
        + (f", planner {args.planner}" if args.planner != "mpfc" else "")
        + (f", segmenter {args.segmenter}" if args.segmenter != "s3" else "")
        + (", with the SLIP guide" if args.guide else ""),
        "trials": len(trials),
        "success_ratio": ok / len(trials),
        "falls": sum(t.fell for t in trials),
        "distance_m": float(np.mean([t.distance_m for t in trials])),
        "mean_velocity_mps": float(np.mean([t.mean_velocity_mps for t in trials])),
        "commanded_velocity_mps": args.vx,
        "footsteps": sum(t.footsteps for t in trials),
        "footsteps_outside": sum(t.footsteps_outside for t in trials),
        "sim_duration_s": args.duration,
        "reached_goal_s": float(np.mean([t.reached_goal_s for t in trials])),
        "fall_time_s": float(np.mean([t.fall_time_s for t in trials])),
    }
    if args.dmin is not None:
        figures["dmin_m"] = args.dmin
    if args.depth is not None:
        figures["stair_depth_m"] = args.depth
    if args.width is not None:
        figures[f"{args.name}_width_m"] = args.width
    figures["guide"] = args.guide
    if args.launch:
        figures["mode"] = args.launch
        figures["description"] = f"{args.name} with cassie launch in {args.launch} mode"
        for i, tr in enumerate(trials):
            pre = "" if len(trials) == 1 else f"trial{i}/"
            for key, row in tr.timing.items():
                for k, v in row.items():
                    figures[f"{pre}{key}/{k}"] = v
            for name, row in (tr.cpu.get("processes") or {}).items():
                figures[f"{pre}cpu/{name}/share"] = row["cpu_share"]
            if tr.cpu:
                figures[f"{pre}cpu/total_share"] = tr.cpu["total_share"]
            for k in ("rtf", "states_per_packet", "torques_per_step"):
                if k in tr.realtime:
                    figures[f"{pre}realtime/{k}_ratio"] = tr.realtime[k]
            figures[f"{pre}fell"] = tr.fell
            figures[f"{pre}mean_velocity_mps"] = tr.mean_velocity_mps
    print(f"\n{ok}/{len(trials)} trials succeeded")
    write_json(args.json, f"experiment_{args.name}", figures)
    return 0


def _cubes_job(job: tuple[float, bool, int, float | None]) -> dict[str, Any]:
    from tools.experiment.obstacles import run_cubes_trial, trial_record

    k, stand, cubes, ov = job
    return trial_record(run_cubes_trial(k, stand, cubes, obstacle_variance=ov))


def _cubes(ap: argparse.ArgumentParser, args: argparse.Namespace) -> int:
    """``cubes``: Table IV, one harness trial per k_hyst, in parallel over the cores."""
    from concurrent.futures import ProcessPoolExecutor

    from tools.experiment.obstacles import HYSTERESIS

    try:
        ks = ([float(x) for x in args.hysteresis.split(",") if x.strip()]
              if args.hysteresis else list(HYSTERESIS))
    except ValueError:
        ap.error(f"--hysteresis {args.hysteresis!r}: want numbers, e.g. 0,0.3,0.6")
    if not all(0.0 <= k <= 1.0 for k in ks) or not 1 <= args.cubes <= 3:
        ap.error("--hysteresis values in [0, 1], --cubes 1 to 3")
    jobs = args.jobs or os.cpu_count() or 1
    mode = "standing" if args.stand else "walking"
    print(f"cubes: {len(ks)} trials ({mode}, {args.cubes} cubes each), {jobs} at a time")
    with ProcessPoolExecutor(jobs) as pool:
        recs = list(pool.map(_cubes_job, [(k, args.stand, args.cubes, args.obstacle_variance)
                                          for k in ks]))
    rows = {}
    figures: dict[str, Any] = {"mode": mode, "obstacle_variance_m2": args.obstacle_variance}
    for r in recs:
        seen = sum(c["seen"] for c in r["cubes"])
        rows[f"k_hyst {r['k_hyst']:g}"] = (
            f"{r['segmented']}/{len(r['cubes'])} segmented out ({seen} seen before the drop)"
            + (", the robot fell" if r["fell"] else ""))
        key = f"k_hyst_{r['k_hyst']:g}".replace(".", "p")
        figures[f"{key}_segmented_count"] = r["segmented"]
        figures[f"{key}_dropped_count"] = len(r["cubes"])
        figures[f"{key}_seen_count"] = seen
        figures[f"{key}_fell"] = r["fell"]
    print_table(f"Table IV: cubes segmented out, {mode}", rows)
    if args.json:
        figures["trials"] = recs
    write_json(args.json, f"experiment_cubes_{mode}", figures)
    return 0


def _sweep(ap: argparse.ArgumentParser, args: argparse.Namespace) -> int:
    """``--sweep PARAM=VALUES``: the trials of every value, in parallel, resumable."""
    from tools.experiment.sweep import TrialSpec, frange, run_sweep, summarise, write_summary

    name, _, values = args.sweep.partition("=")
    allowed = SWEEPS.get(args.name)
    if name != allowed:
        ap.error(f"--sweep for {args.name}: " + (f"{allowed}=LO:HI:STEP" if allowed
                                                 else "nothing to sweep"))
    if args.launch:
        ap.error("--sweep runs in the deterministic harness (no --launch)")
    try:
        grid = frange(values)
    except ValueError as exc:
        ap.error(f"--sweep: {exc}")
    out = args.out or Path(f"sweep_{args.name}_{name}")
    specs = [TrialSpec(args.name, args.duration, args.seed + i,
                       v if name == "dmin" else args.dmin, args.perception, args.vx,
                       str(args.profile),
                       v if name in ("depth", "width") else (args.depth or args.width),
                       fixed_timing=args.fixed_timing, lateral_gain=args.lateral_gain,
                       true_state=args.true_state, planner=args.planner,
                       segmenter=args.segmenter, guide=args.guide, point=(f"{name}_m", v))
             for v in grid for i in range(args.trials)]
    jobs = args.jobs or os.cpu_count() or 1
    print(f"sweep {args.name} {name} over {grid}: {len(specs)} trials, {jobs} at a time, "
          f"seeds {args.seed}..{args.seed + args.trials - 1}; results in {out}")
    result = run_sweep(specs, out, jobs)
    rows = summarise(result.trials)
    feet = "S3" if args.perception else "true"
    timing = "Fixed-T" if args.fixed_timing else "Opt-T"
    if args.true_state:
        timing += ", true state"
    if args.planner != "mpfc":
        timing += f", planner {args.planner}"
    if args.segmenter != "s3":
        timing += f", segmenter {args.segmenter}"
    if args.guide:
        timing += ", SLIP guide"
    png = write_summary(rows, result, out, f"{args.name}: {len(specs) // max(len(grid), 1)} "
                        f"trials per point, {feet} footholds, {timing}", jobs)
    print_table(f"sweep {args.name} over {name}", {
        f"{r['value']:g}": f"success {100 * r['success_rate']:.0f} %, crossed "
        f"{100 * r['crossed_rate']:.0f} %, {r['falls']} falls, {r['mean_distance_m']:.2f} m"
        for r in rows})
    per_hour = 3600.0 * result.ran / result.wall_s if result.ran and result.wall_s else 0.0
    print(f"ran {result.ran} trial(s) now ({len(result.trials) - result.ran} were done "
          f"before) in {result.wall_s:.0f} s: {per_hour:.0f} trials per hour on {jobs} "
          f"job(s); {out / 'summary.json'}, {png}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
