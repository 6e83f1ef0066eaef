"""`cassie bench slip`: the SLIP guide planner's solve times and reweighting iterations on the
scenes of Bartlett & Manchester's Table I (flat, stepping stones, chasm, staircase up) at
horizons 1.5 / 3.0 / 4.5 s and k = 10 / 20 candidates per time step, v = 0.32 m/s,
t = 0.15 s, beside the paper's figures (MOSEK on an i7 at 3.0 GHz).

One plan is Algorithm 1 from the candidates on: the RKNN search, the friction prefilter and
every QP (piqp) until no time step has more than two contacts. The candidate sampling of the
footholds is timed apart (``sample``): the paper's cost map is an input, ours is made from
the footholds. The default run is small (3 trials of each setting); ``--table1`` is the
paper's 10 trials of every scene, horizon and k.
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

from processes.slip_guide.params import SlipParams
from processes.slip_guide.phases import assign_phases
from processes.slip_guide.planner import SlipPlan, SlipPlanner
from runtime.config import HW_CONFIG_DIR
from runtime.params import load
from tools.benchmarks.common import (
    machine_description,
    print_columns,
    print_table,
    progress,
    summarize,
    write_json,
)
from tools.testbed.slip_scenes import SCENES, SPEED_MPS, Scene, problem, scene

DEFAULT_CONFIG = HW_CONFIG_DIR / "gains" / "slip_guide.yaml"
HORIZONS_S = (1.5, 3.0, 4.5)
KS = (10, 20)

#: Table I of the paper: solve time (s) mean and SD at (T, k), and the reweighting
#: iterations avg / min / max per environment (the paper's row names in the comments)
PAPER_S: dict[str, dict[tuple[float, int], tuple[float, float]]] = {
    "flat": {(1.5, 20): (0.0442, 0.0018), (3.0, 20): (0.154, 0.004),  # Flat Ground
             (4.5, 20): (0.607, 0.18), (1.5, 10): (0.0182, 0.0042)},
    "stones": {(1.5, 20): (0.0357, 0.0013), (3.0, 20): (0.183, 0.0042),  # Step Stones
               (4.5, 20): (0.958, 0.25), (1.5, 10): (0.0178, 0.0021)},
    "chasm": {(1.5, 20): (0.0565, 0.034), (3.0, 20): (0.17, 0.05),  # Chasm
              (4.5, 20): (0.819, 0.086), (1.5, 10): (0.0154, 0.00044)},
    "stairs": {(1.5, 20): (0.169, 0.031), (3.0, 20): (0.334, 0.26),  # Staircase (Up)
               (4.5, 20): (0.592, 0.012), (1.5, 10): (0.016, 0.00052)},
}
#: Table I's second k = 20 column at T = 1.5 s (its "Surfaces at each time" block) differs
#: from the first (the same setting): flat 0.0417 +- 0.013, stones 0.0297 +- 0.0012, chasm
#: 0.0431 +- 0.0087, stairs 0.0407 +- 0.01 s; the report sets both beside ours
PAPER_K20_S = {"flat": (0.0417, 0.013), "stones": (0.0297, 0.0012),
               "chasm": (0.0431, 0.0087), "stairs": (0.0407, 0.01)}
PAPER_RW = {"flat": (1.12, 1, 3), "stones": (1.62, 1, 4), "chasm": (1.38, 1, 6),
            "stairs": (1.34, 1, 10)}


def settings(table1: bool) -> list[tuple[float, int]]:
    """The (T, k) pairs timed: Table I's four, or every horizon at every k."""
    if table1:
        return [(t, k) for t in HORIZONS_S for k in KS]
    return [(1.5, 20), (3.0, 20), (4.5, 20), (1.5, 10)]


def outside_every_foothold(sc: Scene, plan: SlipPlan) -> int:
    """How many chosen contacts lie on no foothold (to 1 mm)."""
    pts = plan.positions[plan.chosen]
    return sum(not any(f.contains(p, tol=1e-3) for f in sc.footholds) for p in pts)


def run(params: SlipParams, scenes: tuple[str, ...], pairs: list[tuple[float, int]],
        trials: int) -> tuple[dict[str, object], dict[str, SlipPlan]]:
    """Every (scene, T, k, trial) plan: the flat figure dict, and the first trial's plan of
    each scene at 3 s (k = 20) for the drawing."""
    figs: dict[str, object] = {"trials": trials, "speed_mps": SPEED_MPS,
                               "dt_s": params.dt_s}
    drawn: dict[str, SlipPlan] = {}
    bar = progress(len(scenes) * len(pairs) * trials, "SLIP plans", unit="plan")
    try:
        for name in scenes:
            iters_all: list[int] = []
            for horizon, k in pairs:
                p = dataclasses.replace(params, horizon_s=horizon, knn_k=k)
                planner = SlipPlanner(p)
                wall, cpu, qp, sample, iters, card, bad, steps = [], [], [], [], [], [], [], []
                statuses: dict[str, int] = {}
                stops: dict[str, int] = {}
                for trial in range(trials):
                    sc = scene(name, trial)
                    t0 = time.perf_counter()
                    s_ref, v_ref, cands = problem(sc, p)
                    sample.append((time.perf_counter() - t0) * 1e3)
                    gc.collect()
                    gc.disable()
                    try:
                        c0 = time.thread_time()
                        plan = planner.plan(s_ref[0], v_ref[0], s_ref, v_ref, cands)
                        cpu.append((time.thread_time() - c0) * 1e3)
                    finally:
                        gc.enable()
                    wall.append(plan.wall_s * 1e3)
                    qp.append(plan.qp_wall_s * 1e3)
                    iters.append(plan.iterations)
                    card.append(int(plan.contacts_per_step.max(initial=0)))
                    bad.append(outside_every_foothold(sc, plan))
                    steps.append(len(assign_phases(plan, p.dt_s, p.merge_radius_m)))
                    statuses[plan.status] = statuses.get(plan.status, 0) + 1
                    stops[plan.stopped] = stops.get(plan.stopped, 0) + 1
                    if trial == 0 and (horizon, k) == (3.0, 20):
                        drawn[name] = plan
                    bar.update(1)
                key = f"{name}_T{horizon:g}s_k{k}"
                w = np.asarray(wall)
                figs.update(summarize(w, f"{key}_plan_wall"))
                figs[f"{key}_plan_wall_sd_ms"] = float(w.std(ddof=1)) if len(w) > 1 else 0.0
                figs.update(summarize(np.asarray(cpu), f"{key}_plan_cpu"))
                figs[f"{key}_plan_cpu_sd_ms"] = float(np.std(cpu, ddof=1)) if len(cpu) > 1 \
                    else 0.0
                figs[f"{key}_qp_wall_mean_ms"] = float(np.mean(qp))
                figs[f"{key}_sample_wall_mean_ms"] = float(np.mean(sample))
                figs[f"{key}_iterations_mean"] = float(np.mean(iters))
                figs[f"{key}_iterations_min"] = int(np.min(iters))
                figs[f"{key}_iterations_max"] = int(np.max(iters))
                figs[f"{key}_card_max"] = int(np.max(card))
                figs[f"{key}_card_over_2_count"] = int(np.sum(np.asarray(card) > 2))
                figs[f"{key}_contacts_outside_footholds_count"] = int(np.sum(bad))
                figs[f"{key}_steps_mean"] = float(np.mean(steps))
                figs[f"{key}_status_solved_count"] = statuses.get("solved", 0)
                for why in ("card", "iterations", "qp_infeasible", "qp_failed"):
                    figs[f"{key}_stopped_{why}_count"] = stops.get(why, 0)
                iters_all += iters
            figs[f"{name}_iterations_mean"] = float(np.mean(iters_all))
            figs[f"{name}_iterations_min"] = int(np.min(iters_all))
            figs[f"{name}_iterations_max"] = int(np.max(iters_all))
    finally:
        bar.close()
    return figs, drawn


def table_rows(figs: dict[str, object], scenes: tuple[str, ...],
               pairs: list[tuple[float, int]]) -> list[list[object]]:
    """One row per scene and setting: ours (median, mean +- SD, max wall; mean CPU; QP;
    iterations; the most contacts at a time step; why Algorithm 1 stopped: (5) met, n_rw
    spent, a reweighted QP without a solution) beside the paper's mean +- SD."""
    rows: list[list[object]] = []
    for name in scenes:
        for horizon, k in pairs:
            key = f"{name}_T{horizon:g}s_k{k}"
            paper = PAPER_S[name].get((horizon, k))
            qp_stops = (figs[f"{key}_stopped_qp_infeasible_count"]
                        + figs[f"{key}_stopped_qp_failed_count"])
            rows.append([
                name, f"{horizon:g}", k,
                f"{figs[f'{key}_plan_wall_median_ms']:.1f}",
                f"{figs[f'{key}_plan_wall_mean_ms']:.1f} +- {figs[f'{key}_plan_wall_sd_ms']:.1f}",
                f"{figs[f'{key}_plan_wall_max_ms']:.1f}",
                f"{figs[f'{key}_plan_cpu_mean_ms']:.1f} +- {figs[f'{key}_plan_cpu_sd_ms']:.1f}",
                f"{figs[f'{key}_qp_wall_mean_ms']:.1f}",
                f"{figs[f'{key}_iterations_mean']:.2f}/{figs[f'{key}_iterations_min']}/"
                f"{figs[f'{key}_iterations_max']}",
                figs[f"{key}_card_max"],
                "/".join(str(figs[f"{key}_stopped_{why}_count"]) for why in ("card", "iterations"))
                + f"/{qp_stops}",
                "" if paper is None else f"{paper[0] * 1e3:.1f} +- {paper[1] * 1e3:.1f}",
            ])
    return rows


def plot(figs: dict[str, object], drawn: dict[str, SlipPlan], scenes: tuple[str, ...],
         out_dir: Path, trials: int) -> list[Path]:
    """Two PNGs: the plan time against the horizon per scene (ours and the paper's), and one
    3 s plan per scene (top and side view: candidates, chosen contacts coloured by time,
    the CoM path)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out_dir.mkdir(parents=True, exist_ok=True)
    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    for i, name in enumerate(scenes):
        colour = f"C{i}"
        hs = [h for h in HORIZONS_S if f"{name}_T{h:g}s_k20_plan_wall_mean_ms" in figs]
        mean = [figs[f"{name}_T{h:g}s_k20_plan_wall_mean_ms"] for h in hs]
        sd = [figs[f"{name}_T{h:g}s_k20_plan_wall_sd_ms"] for h in hs]
        ax.errorbar(hs, mean, yerr=sd, color=colour, marker="o", capsize=3,
                    label=f"{name}: ours (piqp)")
        ax.errorbar(HORIZONS_S, [PAPER_S[name][(h, 20)][0] * 1e3 for h in HORIZONS_S],
                    yerr=[PAPER_S[name][(h, 20)][1] * 1e3 for h in HORIZONS_S], color=colour,
                    marker="s", ls="--", capsize=3, alpha=0.6, label=f"{name}: paper (MOSEK)")
    ax.set_yscale("log")
    ax.set_xlabel("horizon T (s), k = 20, t = 0.15 s")
    ax.set_ylabel("plan time (ms), mean +- SD")
    ax.set_title(f"SLIP planner, Table I scenes ({trials} trials each)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, ncol=2)
    paths = [_save(fig, out_dir / "solve_time_vs_horizon.png")]

    fig, axes = plt.subplots(2, len(drawn), figsize=(4.2 * len(drawn), 5.6), squeeze=False,
                             gridspec_kw={"height_ratios": [1.0, 1.2]})
    for col, (name, plan) in enumerate(drawn.items()):
        top, side = axes[0, col], axes[1, col]
        n = len(plan.s) - 1
        cmap = plt.get_cmap("viridis")
        pts = np.unique(plan.positions, axis=0)
        top.scatter(pts[:, 0], pts[:, 1], s=3, c="0.75", label="candidates")
        side.scatter(pts[:, 0], pts[:, 2], s=3, c="0.75")
        for j in np.flatnonzero(plan.chosen):
            colour = cmap(plan.step[j] / max(n - 1, 1))
            f, s_i = plan.positions[j], plan.s[plan.step[j]]
            top.plot([f[0], s_i[0]], [f[1], s_i[1]], color=colour, lw=0.8)
            side.plot([f[0], s_i[0]], [f[2], s_i[2]], color=colour, lw=0.8)
        ch = plan.chosen
        top.scatter(plan.positions[ch, 0], plan.positions[ch, 1], c=plan.step[ch], cmap=cmap,
                    vmin=0, vmax=n - 1, s=18, zorder=3, label="chosen contacts")
        side.scatter(plan.positions[ch, 0], plan.positions[ch, 2], c=plan.step[ch], cmap=cmap,
                     vmin=0, vmax=n - 1, s=18, zorder=3)
        top.plot(plan.s_ref[:, 0], plan.s_ref[:, 1], "k:", lw=1, label="s*")
        top.plot(plan.s[:, 0], plan.s[:, 1], "r-", lw=1.2, label="CoM s")
        side.plot(plan.s_ref[:, 0], plan.s_ref[:, 2], "k:", lw=1)
        side.plot(plan.s[:, 0], plan.s[:, 2], "r-", lw=1.2)
        top.set_title(f"{name}: {plan.iterations} QP(s), at most "
                      f"{int(plan.contacts_per_step.max())} contacts/step", fontsize=9)
        top.set_aspect("equal")
        top.set_ylim(-0.4, 0.4)
        side.set_xlabel("x (m)")
        top.set_ylabel("y (m)")
        side.set_ylabel("z (m)")
        if col == 0:
            top.legend(fontsize=6, loc="upper left")
    fig.suptitle("One 3 s plan per scene (k = 20): contacts and legs coloured by time step",
                 fontsize=10)
    paths.append(_save(fig, out_dir / "plans.png"))
    return paths


def _save(fig: Any, path: Path) -> Path:
    """Lay out, write and close ``fig``; its path."""
    import matplotlib.pyplot as plt

    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def main(argv: list[str] | None = None) -> int:
    """Entry point of `cassie bench slip`."""
    ap = argparse.ArgumentParser(prog="cassie bench slip", description=__doc__.splitlines()[0])
    ap.add_argument("--json", metavar="FILE", help="write the figures as one flat JSON object")
    ap.add_argument("--trials", type=int, default=None,
                    help="plans per scene and setting (default 3; 10 with --table1)")
    ap.add_argument("--table1", action="store_true",
                    help="the paper's Table I: 10 trials, every horizon at k = 10 and 20")
    ap.add_argument("--scenes", default=",".join(SCENES),
                    help=f"comma-separated, of {', '.join(SCENES)}")
    ap.add_argument("--config", default=str(DEFAULT_CONFIG), help="SLIP guide gains YAML")
    ap.add_argument("--plots", metavar="DIR", help="write solve_time_vs_horizon.png and "
                    "plans.png there")
    args = ap.parse_args(argv)
    scenes = tuple(s for s in args.scenes.split(",") if s)
    unknown = [s for s in scenes if s not in SCENES]
    if unknown:
        ap.error(f"unknown scene(s) {', '.join(unknown)} (allowed: {', '.join(SCENES)})")
    trials = args.trials if args.trials is not None else (10 if args.table1 else 3)
    params = load(SlipParams, args.config)
    pairs = settings(args.table1)
    load_start = os.getloadavg()[0]
    t0 = time.perf_counter()
    figs, drawn = run(params, scenes, pairs, trials)
    figs.update({"bench_wall_s": time.perf_counter() - t0,
                 "load_average_1min_start": load_start,
                 "load_average_1min_end": os.getloadavg()[0]})
    print(f"machine: {machine_description()}")
    print(f"\nSLIP planner (Bartlett & Manchester, Problem 2 + Algorithm 1) on piqp, "
          f"{trials} trials per row, v = {SPEED_MPS} m/s, t = {params.dt_s} s; plan = RKNN + "
          "prefilter + every QP; the paper: MOSEK, i7 3.0 GHz")
    print_columns(["scene", "T [s]", "k", "median [ms]", "mean +- SD [ms]", "max [ms]",
                   "CPU mean +- SD [ms]", "QP [ms]", "RW it avg/min/max", "card max",
                   "stop card/n_rw/QP", "paper mean +- SD [ms]"], table_rows(figs, scenes, pairs))
    print_table("Reweighting iterations per scene (QPs of Algorithm 1), ours | paper",
                [(n, f"{figs[f'{n}_iterations_mean']:.2f}/{figs[f'{n}_iterations_min']}/"
                     f"{figs[f'{n}_iterations_max']}",
                  "{:.2f}/{}/{}".format(*PAPER_RW[n])) for n in scenes])
    if args.plots and drawn:
        for path in plot(figs, drawn, scenes, Path(args.plots), trials):
            print(f"wrote {path}")
    write_json(args.json, "slip", figs)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
