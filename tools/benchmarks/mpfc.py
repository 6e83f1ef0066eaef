"""`cassie bench mpfc`: MPFC solve times (Section VIII-C, Table II) on generated instances,
or (``--closed-loop TERRAIN``) on the solves recorded from closed-loop walking runs.

Instances come in short episodes, as on the robot: a cold solve (new footholds, no previous
plan), then warm solves later in the same stance (state propagated along the ALIP, T*
shrinking, so the previous assignment seeds the search and the trust region binds). Foothold
counts are drawn uniformly from 1..20. With gurobipy installed, Gurobi solves the literal
big-M MIQP of every same instance (tight tolerances, one thread) and its objective is checked.

Figures are measured, never asserted. Targets (the paper's Gurobi figures): median 2 ms,
p99.9 7.7 ms.
"""

from __future__ import annotations

import argparse
import gc
import os
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from processes.footstep_search.miqp import MiqpData
from processes.mpfc import MpfcParams, MpfcSolver
from processes.mpfc.problem import build_miqp
from processes.mpfc.solver import Instance
from tools.benchmarks.common import (
    machine_description,
    print_table,
    progress,
    say,
    summarize,
    write_json,
)
from tools.testbed.gurobi_reference import GurobiBackend, gurobi_available, gurobi_wanted
from tools.testbed.mpfc_instances import random_instance

REPO = Path(__file__).resolve().parents[2]
DEFAULT_CONFIG = REPO / "hw_config" / "gains" / "mpfc.yaml"
TARGET_MEDIAN_MS = 2.0
TARGET_P999_MS = 7.7
WARM_PER_EPISODE = 3
WARM_DT_S = 0.03


def compare_gurobi(backend: GurobiBackend, build: Callable[[Any, Any], MiqpData],
                   problems: list[tuple[Any, ...]], prefix: str) -> dict[str, object]:
    """Gurobi on the literal MIQP (``build(inputs, footholds)``, the planner's) of each
    (inputs, footholds, our status, our objective, our solve ms) problem: its times, the
    ratio to ours, and how the objectives compare (ours higher: Gurobi found a better point;
    Gurobi higher: it stopped short)."""
    g_run, g_wall, g_nodes = [], [], []
    compared = ours_higher = gurobi_higher = status_diff = 0
    max_rel = 0.0
    bar = progress(len(problems), "Gurobi", unit="solve")
    for inp, lf, status, objective, _ in problems:
        g = backend.solve(build(inp, lf))
        g_run.append(g.runtime_ms)
        g_wall.append(g.wall_ms)
        g_nodes.append(g.nodes)
        if status == "optimal" and g.status == "optimal":
            compared += 1
            rel = (objective - g.objective) / max(abs(g.objective), 1.0)
            max_rel = max(max_rel, abs(rel))
            ours_higher += rel > 1e-6
            gurobi_higher += rel < -1e-6
        elif (status == "infeasible") != (g.status == "infeasible"):
            status_diff += 1
        bar.update(1)  # (Gurobi's own runtime and the backend's wall clock are taken inside)
    bar.close()
    gr = np.asarray(g_run)
    ours = np.asarray([p[4] for p in problems])
    figs: dict[str, object] = {}
    figs.update(summarize(gr, f"{prefix}_runtime"))
    figs.update(summarize(np.asarray(g_wall), f"{prefix}_wall"))
    figs.update({
        f"{prefix}_nodes_mean": float(np.mean(g_nodes)),
        f"{prefix}_compared_count": compared,
        f"{prefix}_objective_mismatch_count": ours_higher + gurobi_higher + status_diff,
        f"{prefix}_objective_ours_higher_count": ours_higher,
        f"{prefix}_objective_gurobi_higher_count": gurobi_higher,
        f"{prefix}_status_disagreements": status_diff,
        f"{prefix}_objective_max_rel_diff": max_rel,
        # Gurobi's own optimizer time vs our whole solve (build + search) on the same
        # instances: conservative toward Gurobi
        f"{prefix}_over_ours_median_ratio": float(np.median(gr) / np.median(ours)),
        f"{prefix}_over_ours_p999_ratio": float(np.percentile(gr, 99.9)
                                               / np.percentile(ours, 99.9)),
        f"{prefix}_over_ours_mean_ratio": float(gr.mean() / ours.mean()),
    })
    return figs


def run(params: MpfcParams, solves: int, seed: int, use_gurobi: bool, gurobi_every: int,
        max_footholds: int = 20) -> dict[str, object]:
    """Run `solves` solves; return the flat figure dict."""
    rng = np.random.default_rng(seed)
    solver = MpfcSolver(params)
    model = solver.model
    backend = GurobiBackend() if use_gurobi else None
    wall, cpu, opt, nodes, counts, cold = [], [], [], [], [], []
    statuses: dict[str, int] = {}
    problems = []  # (inputs, footholds, status, objective, wall) for the Gurobi pass
    bar = progress(solves, "MPFC solves", unit="solve")
    gc.collect()
    gc.disable()
    try:
        k = 0
        while k < solves:
            m = int(rng.integers(1, max_footholds + 1))
            inst = random_instance(rng, model, m)
            solver.reset()
            x, t_rem = inst.x_alip.copy(), inst.t_remaining_s
            for j in range(WARM_PER_EPISODE + 1):
                if k >= solves:
                    break
                c0 = time.thread_time()
                sol = solver.solve(x, inst.stance, inst.p_stance, t_rem, inst.vdes,
                                   inst.footholds, inst.yaw)
                cpu.append((time.thread_time() - c0) * 1e3)
                wall.append(sol.solve_wall_ms)
                opt.append(sol.optimizer_ms)
                nodes.append(sol.nodes_explored)
                counts.append(sol.footholds_considered)
                cold.append(j == 0)
                statuses[sol.status] = statuses.get(sol.status, 0) + 1
                if backend is not None and k % gurobi_every == 0:
                    problems.append((solver.last_inputs, solver.last_local, sol.status,
                                     sol.objective, sol.solve_wall_ms))
                k += 1
                bar.update(1)  # after the solve's clocks are read: outside what is timed
                if t_rem - WARM_DT_S <= 0.0:
                    break
                # propagate along the ALIP for WARM_DT_S with small noise, later in the stance
                x = model.expm_a(WARM_DT_S) @ x + rng.normal(0, 1, 4) * [0.003, 0.003, 0.3, 0.3]
                t_rem -= WARM_DT_S
    finally:
        gc.enable()
        bar.close()
    w = np.asarray(wall)
    c = np.asarray(cold)
    figs: dict[str, object] = {"solves": len(w), "seed": seed,
                               "footholds_min": 1, "footholds_max": max_footholds}
    figs.update(summarize(w, "solve"))
    figs.update(summarize(w[c], "solve_cold"))
    figs.update(summarize(w[~c], "solve_warm"))
    figs.update(summarize(np.asarray(opt), "optimizer"))
    # CPU time of the solving thread (measured around the call, so it includes two clock
    # reads): on a shared machine, wall minus CPU is time spent waiting for a core
    figs.update(summarize(np.asarray(cpu), "solve_cpu"))
    nd = np.asarray(nodes)
    figs.update({
        "nodes_mean": float(nd.mean()), "nodes_median": float(np.median(nd)),
        "nodes_p99": float(np.percentile(nd, 99)), "nodes_max": int(nd.max()),
        "footholds_considered_mean": float(np.mean(counts)),
        "over_7p7ms_ratio": float(np.mean(w > TARGET_P999_MS)),
        "over_10ms_ratio": float(np.mean(w > 10.0)),
    })
    cnt = np.asarray(counts)
    for lo, hi in ((1, 5), (6, 10), (11, 15), (16, 20)):
        sel = (cnt >= lo) & (cnt <= hi)
        if sel.any():
            figs[f"solve_median_ms_m{lo}_{hi}"] = float(np.median(w[sel]))
            figs[f"solve_p999_ms_m{lo}_{hi}"] = float(np.percentile(w[sel], 99.9))
    for s in ("optimal", "time_limited", "infeasible"):
        figs[f"status_{s}_count"] = statuses.get(s, 0)
    if backend is not None and problems:
        # Gurobi afterwards, on exactly the problems the search solved, so that neither run
        # disturbs the other's timing
        figs.update(compare_gurobi(backend, lambda i, f: build_miqp(model, i, f), problems,
                                   "gurobi"))
    return figs


def record_closed_loop(terrain: str, seeds: int, seconds: float
                       ) -> tuple[MpfcParams, list[list[Instance]]]:
    """The solve arguments of the MPFC node in closed-loop harness runs of ``cassie
    experiment TERRAIN`` (ground-truth footholds), one episode per seed, in solve order
    (a trial that falls ends its episode). Returns the node's parameters and the episodes."""
    from runtime.config import HW_CONFIG_DIR
    from tools.experiment import run_trial

    params: list[MpfcParams] = []
    episodes: list[list[Instance]] = []
    # a step per run (each run draws its own bar of sim seconds below this one)
    bar = progress(seeds, f"recording {terrain}", unit="run")
    for seed in range(seeds):
        rec: list[Instance] = []

        def attach(h: object, rec: list[Instance] = rec) -> None:
            for b in h.bindings:  # type: ignore[attr-defined]
                solver = getattr(b.node, "solver", None)
                if isinstance(solver, MpfcSolver):
                    solver.recorder = rec
                    params.append(solver.params)

        trial = run_trial(terrain, seconds, seed, None, False, 0.375,
                          HW_CONFIG_DIR / "experiment.yaml", setup=attach)
        say(f"  recorded {len(rec)} solves: {terrain} seed {seed}, "
            f"{trial.duration_s:.1f} s walked{' (fell)' if trial.fell else ''}", sys.stderr)
        episodes.append(rec)
        bar.update(1)
    bar.close()
    if not params:
        raise SystemExit("the experiment profile has no MPFC node: nothing to record")
    return params[0], episodes


def replay(params: MpfcParams, episodes: list[list[Instance]], use_gurobi: bool = False
           ) -> dict[str, object]:
    """Time a fresh solver on each recorded episode in order (warm starts as live); with
    ``use_gurobi``, Gurobi on the literal MIQP of every same problem afterwards."""
    wall, nodes, counts = [], [], []
    statuses: dict[str, int] = {}
    problems = []  # (inputs, footholds, status, objective, wall) for the Gurobi pass
    model = MpfcSolver(params).model
    bar = progress(sum(len(ep) for ep in episodes), "replayed solves", unit="solve")
    gc.collect()
    gc.disable()
    try:
        for ep in episodes:
            solver = MpfcSolver(params)
            for inst in ep:
                sol = solver.solve(inst.x_alip, inst.stance, inst.p_stance, inst.t_remaining_s,
                                   inst.vdes, inst.footholds, inst.yaw)
                wall.append(sol.solve_wall_ms)
                nodes.append(sol.nodes_explored)
                counts.append(sol.footholds_considered)
                statuses[sol.status] = statuses.get(sol.status, 0) + 1
                if use_gurobi:
                    problems.append((solver.last_inputs, solver.last_local, sol.status,
                                     sol.objective, sol.solve_wall_ms))
                bar.update(1)  # (the solver times itself: this is outside its clocks)
    finally:
        gc.enable()
        bar.close()
    w = np.asarray(wall)
    figs: dict[str, object] = {"closed_loop_solves": int(w.size)}
    figs.update(summarize(w, "closed_loop_solve"))
    if problems:
        figs.update(compare_gurobi(GurobiBackend(), lambda i, f: build_miqp(model, i, f),
                                   problems, "closed_loop_gurobi"))
    cnt = np.asarray(counts)
    figs.update({
        "closed_loop_nodes_mean": float(np.mean(nodes)),
        "closed_loop_nodes_max": int(np.max(nodes)),
        "closed_loop_footholds_min": int(cnt.min()),
        "closed_loop_footholds_max": int(cnt.max()),
        "closed_loop_footholds_mean": float(cnt.mean()),
        "closed_loop_over_7p7ms_ratio": float(np.mean(w > TARGET_P999_MS)),
    })
    for st in ("optimal", "time_limited", "infeasible"):
        figs[f"closed_loop_status_{st}_count"] = statuses.get(st, 0)
    figs.update(retime_slowest(params, episodes, w))
    return figs


def retime_slowest(params: MpfcParams, episodes: list[list[Instance]], wall: np.ndarray,
                   count: int = 3, repeats: int = 3) -> dict[str, float]:
    """The ``count`` slowest solves timed again, each ``repeats`` times in the same solver
    state (a fresh solver replays its episode up to it, untimed): a solve that is slow again
    is a hard instance, one that is fast was the machine stalling (this VM stalls for ms)."""
    starts = np.cumsum([0] + [len(ep) for ep in episodes])
    out: dict[str, float] = {}
    for rank, k in enumerate(np.argsort(wall)[::-1][:count]):
        e = int(np.searchsorted(starts, k, side="right") - 1)
        i = int(k - starts[e])
        again = []
        for _ in range(repeats):
            solver = MpfcSolver(params)
            for inst in episodes[e][:i]:
                solver.solve(inst.x_alip, inst.stance, inst.p_stance, inst.t_remaining_s,
                             inst.vdes, inst.footholds, inst.yaw)
            inst = episodes[e][i]
            sol = solver.solve(inst.x_alip, inst.stance, inst.p_stance, inst.t_remaining_s,
                               inst.vdes, inst.footholds, inst.yaw)
            again.append(sol.solve_wall_ms)
        out[f"closed_loop_slowest{rank + 1}_ms"] = float(wall[k])
        out[f"closed_loop_slowest{rank + 1}_retimed_median_ms"] = float(np.median(again))
    return out


def main(argv: list[str] | None = None) -> int:
    """Entry point of `cassie bench mpfc`."""
    ap = argparse.ArgumentParser(prog="cassie bench mpfc", description=__doc__.splitlines()[0])
    ap.add_argument("--json", metavar="FILE", help="write the figures as one flat JSON object")
    ap.add_argument("--solves", type=int, default=10_000, help="number of solves (10000)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--config", default=str(DEFAULT_CONFIG), help="MPFC gains YAML")
    ap.add_argument("--variant", default="hardware", choices=("hardware", "simulation"))
    ap.add_argument("--no-gurobi", action="store_true", help="skip Gurobi even if installed")
    ap.add_argument("--gurobi-every", type=int, default=1,
                    help="compare Gurobi on every k-th solve (1: all)")
    ap.add_argument("--closed-loop", metavar="TERRAIN", default=None,
                    help="instead: record the MPFC's solves in closed-loop harness runs of "
                         "cassie experiment TERRAIN (e.g. stones) and time them")
    ap.add_argument("--seeds", type=int, default=4, help="--closed-loop: runs (terrain seeds)")
    ap.add_argument("--seconds", type=float, default=6.0, help="--closed-loop: sim s per run")
    args = ap.parse_args(argv)
    if args.closed_loop:
        t0 = time.perf_counter()
        cl_params, episodes = record_closed_loop(args.closed_loop, args.seeds, args.seconds)
        load_start = os.getloadavg()[0]
        use_gurobi = not args.no_gurobi and gurobi_available()
        figs = replay(cl_params, episodes, use_gurobi)
        figs["gurobi_installed"] = use_gurobi
        figs.update({"terrain": args.closed_loop, "episodes": len(episodes),
                     "bench_wall_s": time.perf_counter() - t0,
                     "load_average_1min_start": load_start,
                     "load_average_1min_end": os.getloadavg()[0],
                     "target_median_ms": TARGET_MEDIAN_MS, "target_p999_ms": TARGET_P999_MS})
        print(f"machine: {machine_description()}")
        print_table(f"MPFC on closed-loop instances ({args.closed_loop}, {len(episodes)} runs)",
                    list(figs.items()))
        write_json(args.json, "mpfc_closed_loop", figs)
        return 0
    from runtime.params import load  # the gains file, in a column of Table V
    params = load(MpfcParams, args.config, args.variant)
    use_gurobi = gurobi_wanted(args.no_gurobi)
    load_start = os.getloadavg()[0]
    t0 = time.perf_counter()
    figs = run(params, args.solves, args.seed, use_gurobi, max(1, args.gurobi_every))
    figs["bench_wall_s"] = time.perf_counter() - t0
    figs["load_average_1min_start"] = load_start
    figs["load_average_1min_end"] = os.getloadavg()[0]
    figs["gurobi_installed"] = use_gurobi
    figs["target_median_ms"] = TARGET_MEDIAN_MS
    figs["target_p999_ms"] = TARGET_P999_MS
    print(f"machine: {machine_description()}")
    keys = [k for k in figs
            if k.startswith(("solve_", "optimizer_", "nodes_", "over_", "load_"))]
    print_table(f"MPFC exact search (piqp), {figs['solves']} solves, 1-20 footholds",
                [(k, figs[k]) for k in keys])
    print_table("Statuses", [(k, v) for k, v in figs.items() if k.startswith("status_")])
    if use_gurobi:
        print_table("Gurobi on the same instances",
                    [(k, v) for k, v in figs.items() if k.startswith("gurobi_")])
    write_json(args.json, "mpfc", figs)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
