"""`cassie bench dcm`: the DCM planner's solve times and optimality (Xiang et al., Section IV:
13 +- 3 ms, 8-19 ms, Python + Gurobi) on generated instances, Gurobi beside it.

The instances are the MPFC benchmark's (``tools.testbed.mpfc_instances``: an ALIP state, a
stance, T*, a command and 1-20 random footholds around the stance foot), in the same short
episodes (a cold solve, then warm ones later in the stance), with a previous stance foot
behind and to the swing side for the double stance's ramp. The planner gets them as the
footstep-planner process gives them (``DcmSolver.solve``). With gurobipy installed, Gurobi
solves the literal big-M MIQP of every instance afterwards (``DcmModel.build_miqp``), so
neither run disturbs the other's timing: the objectives and statuses are compared, and its
own optimizer time set beside our whole solve.
"""

from __future__ import annotations

import argparse
import dataclasses
import gc
import os
import time

import numpy as np

from processes.dcm_planner.params import VARIANTS, DcmParams
from processes.dcm_planner.solver import DcmSolver
from processes.mpfc import MpfcParams, MpfcSolver
from processes.mpfc.solver import SupportTransfer
from runtime.config import HW_CONFIG_DIR
from runtime.params import load
from tools.benchmarks.common import (
    machine_description,
    print_table,
    progress,
    summarize,
    write_json,
)
from tools.benchmarks.mpfc import WARM_DT_S, WARM_PER_EPISODE, compare_gurobi
from tools.testbed.gurobi_reference import GurobiBackend, gurobi_wanted
from tools.testbed.mpfc_instances import random_instance

DEFAULT_CONFIG = HW_CONFIG_DIR / "gains" / "dcm_planner.yaml"
PAPER_MEAN_MS, PAPER_SD_MS, PAPER_RANGE_MS = 13.0, 3.0, (8.0, 19.0)  # Section IV


def run(params: DcmParams, solves: int, seed: int, use_gurobi: bool,
        max_footholds: int = 20) -> dict[str, object]:
    """``solves`` solves in episodes; the flat figure dict (Gurobi's figures prefixed)."""
    rng = np.random.default_rng(seed)
    solver = DcmSolver(params)
    # the instance generator and the ALIP propagation between warm solves are the MPFC's
    alip = MpfcSolver(load(MpfcParams, HW_CONFIG_DIR / "gains" / "mpfc.yaml",
                           "simulation")).model
    wall, cpu, nodes, counts, cold = [], [], [], [], []
    statuses: dict[str, int] = {}
    problems = []
    bar = progress(solves, f"DCM solves (variant {params.variant})", unit="solve")
    gc.collect()
    gc.disable()
    try:
        k = 0
        while k < solves:
            inst = random_instance(rng, alip, int(rng.integers(1, max_footholds + 1)))
            side = 1.0 if inst.stance == "right" else -1.0  # the swing foot's side
            c, s = np.cos(inst.yaw), np.sin(inst.yaw)
            back = np.array([rng.uniform(-0.35, 0.05), side * rng.uniform(0.1, 0.35)])
            prev = inst.p_stance + np.array([c * back[0] - s * back[1],
                                             s * back[0] + c * back[1], 0.0])
            solver.reset()
            x, t_rem = inst.x_alip.copy(), inst.t_remaining_s
            for j in range(WARM_PER_EPISODE + 1):
                if k >= solves:
                    break
                c0 = time.thread_time()
                sol = solver.solve(x, inst.stance, inst.p_stance, t_rem, inst.vdes,
                                   inst.footholds, inst.yaw,
                                   SupportTransfer(prev, 0.0, params.t_ds_s))
                cpu.append((time.thread_time() - c0) * 1e3)
                wall.append(sol.solve_wall_ms)
                nodes.append(sol.nodes_explored)
                counts.append(sol.footholds_considered)
                cold.append(j == 0)
                statuses[sol.status] = statuses.get(sol.status, 0) + 1
                if use_gurobi:
                    problems.append((solver.last_inputs, solver.last_local, sol.status,
                                     sol.objective, sol.solve_wall_ms))
                k += 1
                bar.update(1)
                if t_rem - WARM_DT_S <= 0.0:
                    break
                x = alip.expm_a(WARM_DT_S) @ x + rng.normal(0, 1, 4) * [0.003, 0.003, 0.3, 0.3]
                t_rem -= WARM_DT_S
    finally:
        gc.enable()
        bar.close()
    w, cmask = np.asarray(wall), np.asarray(cold)
    figs: dict[str, object] = {"solves": len(w), "seed": seed, "variant": params.variant,
                               "footholds_max": max_footholds}
    figs.update(summarize(w, "solve"))
    figs.update(summarize(w[cmask], "solve_cold"))
    figs.update(summarize(w[~cmask], "solve_warm"))
    figs.update(summarize(np.asarray(cpu), "solve_cpu"))
    nd = np.asarray(nodes)
    figs.update({"nodes_mean": float(nd.mean()), "nodes_max": int(nd.max()),
                 "footholds_considered_mean": float(np.mean(counts)),
                 "paper_mean_ms": PAPER_MEAN_MS, "paper_sd_ms": PAPER_SD_MS,
                 "paper_min_ms": PAPER_RANGE_MS[0], "paper_max_ms": PAPER_RANGE_MS[1]})
    for st in ("optimal", "time_limited", "infeasible"):
        figs[f"status_{st}_count"] = statuses.get(st, 0)
    if problems:
        figs.update(compare_gurobi(GurobiBackend(), solver.model.build_miqp, problems,
                                   "gurobi"))
    return figs


def main(argv: list[str] | None = None) -> int:
    """Entry point of `cassie bench dcm`."""
    ap = argparse.ArgumentParser(prog="cassie bench dcm", description=__doc__.splitlines()[0])
    ap.add_argument("--json", metavar="FILE", help="write the figures as one flat JSON object")
    ap.add_argument("--solves", type=int, default=2000, help="number of solves (2000)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--config", default=str(DEFAULT_CONFIG), help="DCM planner gains YAML")
    ap.add_argument("--variant", default="A", choices=VARIANTS,
                    help="A the planner, B fixed step, C N = 2, D no viability constraints")
    ap.add_argument("--no-gurobi", action="store_true", help="skip Gurobi even if installed")
    args = ap.parse_args(argv)
    # no time budget: every solve runs to the proven optimum, so Gurobi's can be compared
    params = dataclasses.replace(load(DcmParams, args.config), variant=args.variant,
                                 time_limit_ms=1e9)
    use_gurobi = gurobi_wanted(args.no_gurobi)
    load_start = os.getloadavg()[0]
    t0 = time.perf_counter()
    figs = run(params, args.solves, args.seed, use_gurobi)
    figs.update({"bench_wall_s": time.perf_counter() - t0, "gurobi_installed": use_gurobi,
                 "load_average_1min_start": load_start,
                 "load_average_1min_end": os.getloadavg()[0]})
    print(f"machine: {machine_description()}")
    print_table(f"DCM planner (variant {args.variant}), exact search on piqp, "
                f"{figs['solves']} solves, 1-20 footholds; the paper: "
                f"{PAPER_MEAN_MS:g} +- {PAPER_SD_MS:g} ms ({PAPER_RANGE_MS[0]:g}-"
                f"{PAPER_RANGE_MS[1]:g} ms) with Gurobi",
                [(k, v) for k, v in figs.items()
                 if k.startswith(("solve_", "nodes_", "status_", "load_"))])
    if use_gurobi:
        print_table("Gurobi on the same instances",
                    [(k, v) for k, v in figs.items() if k.startswith("gurobi_")])
    write_json(args.json, f"dcm_{args.variant}", figs)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
