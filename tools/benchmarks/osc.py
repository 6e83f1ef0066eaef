"""`cassie bench osc`: OSC tick time (build + solve of the QP (14)) on recorded robot states.

States are recorded first from closed-loop MuJoCo runs at 2 kHz in lockstep: a standing run,
then a walking run (standing hand-over, then walking at 0.375 m/s on the plans of the MPFC
node of ``hw_config/sim.yaml``, solved at 200 Hz on the true state). A fresh controller then
replays each recording in order, and every ``update`` call is timed (wall clock), with piqp's
share measured separately. The collector is disabled during the timed loops, as the live OSC
loop does. Figures are printed and optionally written as flat JSON; nothing is asserted.

``--baseline REV`` also replays the same states through the OSC of git revision REV
(``processes/osc`` and ``hw_config/gains/osc.yaml`` extracted with ``git archive`` into a
temporary folder and imported from there), in repeats interleaved with this tree's so both
see the same machine load, and prints both side by side with their ratio and the largest
difference between the two versions' torques. ``--optimality`` checks (untimed) each QP
answer against the same QP's optimum from a tightly converged piqp.
"""

from __future__ import annotations

import argparse
import gc
import os
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from tools.benchmarks.common import (
    extract_tree,
    print_table,
    progress,
    summarize,
    write_json,
)

DEADLINE_MS = 1.0


def _record(kind: str, ticks: int) -> list[tuple[float, np.ndarray, np.ndarray, Any, Any]]:
    """Run the OSC closed loop in MuJoCo and keep (t, q, v, plan, command) of every tick."""
    import mujoco

    from lcmtypes import command_t, robot_state_t
    from processes.osc.controller import SAFE, OscController
    from processes.osc.model import load_cassie, standing_pose
    from runtime.config import HW_CONFIG_DIR, load_profile
    from runtime.driver import NodeDriver

    m = load_cassie()
    m.opt.impratio = 10.0
    d = mujoco.MjData(m)
    d.qpos[:] = standing_pose(m)
    mujoco.mj_forward(m, d)
    osc = OscController()
    profile = load_profile(HW_CONFIG_DIR / "sim.yaml")
    mpfc = NodeDriver.from_config(profile.processes["mpfc"], profile)
    cmd = command_t()
    cmd.mode = 1
    cmd.vx = 0.375
    plan = None
    out: list[tuple[float, np.ndarray, np.ndarray, Any, Any]] = []
    bar = progress(ticks, f"recording {kind}", unit="tick")
    for k in range(ticks):
        t = float(d.time)
        if kind == "walking" and t >= 0.25:
            cmd.mode = 0
            if k % 10 == 0:  # the MPFC at 200 Hz, on the true state
                s = robot_state_t()
                s.header.utime = round(t * 1e6)
                s.num_positions, s.num_velocities = m.nq, m.nv
                s.q, s.v = d.qpos.tolist(), d.qvel.tolist()
                mpfc.tick(state=s, command=cmd)
                plan = mpfc.sent["plan"][-1]
        cmd.yaw_rate = -2.0 * osc.model.pelvis_yaw() if k > 0 else 0.0  # operator steering
        c = None
        if kind == "walking":
            c = command_t()
            c.mode, c.yaw_rate = cmd.mode, cmd.yaw_rate
        out.append((t, d.qpos.copy(), d.qvel.copy(), plan, c))
        u, dbg = osc.update(t, d.qpos, d.qvel, plan, c)
        if dbg.mode == SAFE:  # stop recording before the robot is on the ground
            break
        d.ctrl[:] = u / osc.model.gear
        mujoco.mj_step(m, d)
        bar.update(1)
    bar.close()
    return out


@dataclass
class Replay:
    """Per-tick figures of one replay: wall and CPU time (ms), piqp's share (ms), piqp
    iterations (0: solved in closed form), mode and the torques (N m)."""

    tick: np.ndarray
    cpu: np.ndarray
    solve: np.ndarray
    iters: np.ndarray
    mode: np.ndarray
    u: np.ndarray


def _replay(states: list[tuple[float, np.ndarray, np.ndarray, Any, Any]],
            controller: Callable[[], Any] | None = None, desc: str = "replay") -> Replay:
    """Time every tick of a fresh controller on the recorded states (ms): wall clock, and
    this thread's CPU time (which a busy shared machine inflates much less).
    ``controller`` builds the controller to time (default: this tree's ``OscController``);
    ``desc`` names the progress bar."""
    if controller is None:
        from processes.osc.controller import OscController as controller

    osc = controller()
    n = len(states)
    tick, cpu, solve, iters = np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n)
    mode, us = np.zeros(n, dtype=int), np.zeros((n, 10))
    bar = progress(n, desc, unit="tick")
    gc.collect()
    gc.disable()
    try:
        for i, (t, q, v, plan, cmd) in enumerate(states):
            c0 = time.thread_time()
            t0 = time.perf_counter()
            u, dbg = osc.update(t, q, v, plan, cmd)
            tick[i] = (time.perf_counter() - t0) * 1e3
            cpu[i] = (time.thread_time() - c0) * 1e3
            solve[i] = dbg.solve_ms
            iters[i] = dbg.qp_iterations
            mode[i] = dbg.mode
            us[i] = u
            bar.update(1)  # after both clocks are read: outside the timed tick
    finally:
        gc.enable()
        bar.close()
    return Replay(tick, cpu, solve, iters, mode, us)


def baseline_controller(rev: str) -> Callable[[], Any]:
    """A factory of the ``OscController`` of git revision ``rev``: its ``processes/osc``
    imported beside this tree's as package ``baseline_osc`` (its imports of ``runtime`` resolve
    to this tree's), with that revision's ``hw_config/gains/osc.yaml``."""
    import importlib
    import sys

    gains = "hw_config/gains/osc.yaml"
    root = extract_tree(rev, ("processes/osc", gains))
    # root/pkg/baseline_osc: the package's parents[2] is root, where its gains file lies
    (root / "pkg").mkdir()
    (root / "processes" / "osc").rename(root / "pkg" / "baseline_osc")
    sys.path.insert(0, str(root / "pkg"))
    cls = importlib.import_module("baseline_osc.controller").OscController
    gains_file = root / gains
    return lambda: cls(gains_file=gains_file)


def _stats(a: np.ndarray) -> tuple[float, float, float]:
    return float(np.median(a)), float(np.percentile(a, 99)), float(a.max())


def side_by_side(runs: dict[str, list[tuple[float, np.ndarray, np.ndarray, Any, Any]]],
                 baseline: Callable[[], Any], rev: str, repeats: int = 3) -> dict[str, Any]:
    """Replay every recording through the baseline and this tree's controller in interleaved
    repeats (baseline, this, baseline, ...); print and return the figures, the ratios and the
    torque agreement of the two versions."""
    from processes.osc.controller import OscController

    out: dict[str, Any] = {"baseline_rev": rev, "side_by_side_repeats": repeats}
    rows: list[tuple[str, object]] = []
    for kind, states in runs.items():
        got: dict[str, list[Replay]] = {"baseline": [], "this": []}
        for k in range(repeats):
            got["baseline"].append(_replay(states, baseline, f"{kind} baseline {k + 1}/{repeats}"))
            got["this"].append(_replay(states, OscController, f"{kind} this {k + 1}/{repeats}"))
        for name, reps in got.items():
            for what in ("tick", "cpu"):
                a = np.concatenate([getattr(r, what) for r in reps])
                med, p99, mx = _stats(a)
                key = f"{kind}_{name}_{'tick' if what == 'tick' else 'tick_cpu'}"
                out[f"{key}_median_ms"], out[f"{key}_p99_ms"], out[f"{key}_max_ms"] = med, p99, mx
            r0 = reps[0]
            piqp = r0.iters > 0
            out[f"{kind}_{name}_piqp_ticks"] = int(piqp.sum())
            out[f"{kind}_{name}_piqp_ratio"] = float(piqp.mean())
            if piqp.any():  # the whole tick on the ticks that called piqp
                a = np.concatenate([r.cpu[r.iters > 0] for r in reps])
                out[f"{kind}_{name}_piqp_tick_cpu_median_ms"] = float(np.median(a))
                out[f"{kind}_{name}_piqp_tick_cpu_p99_ms"] = float(np.percentile(a, 99))
            base_piqp = got["baseline"][0].iters > 0
            if base_piqp.any():  # this tree on the ticks where the baseline needed piqp
                a = np.concatenate([r.cpu[base_piqp] for r in reps])
                out[f"{kind}_{name}_on_baseline_piqp_ticks_cpu_median_ms"] = float(np.median(a))
                out[f"{kind}_{name}_on_baseline_piqp_ticks_cpu_p99_ms"] = float(
                    np.percentile(a, 99))
        for stat in ("median", "p99", "max"):
            for what in ("tick", "tick_cpu"):
                b = out[f"{kind}_baseline_{what}_{stat}_ms"]
                t = out[f"{kind}_this_{what}_{stat}_ms"]
                out[f"{kind}_{what}_{stat}_speedup_ratio"] = b / t
        # torque agreement (the replays are deterministic: the first repeat of each suffices)
        ub, ut = got["baseline"][0], got["this"][0]
        du = np.abs(ub.u - ut.u).max(axis=1)
        base_piqp = ub.iters > 0
        out[f"{kind}_torque_diff_max_nm"] = float(du.max())
        out[f"{kind}_torque_diff_median_nm"] = float(np.median(du))
        out[f"{kind}_torque_diff_max_closed_form_ticks_nm"] = float(
            du[~base_piqp].max()) if (~base_piqp).any() else 0.0
        out[f"{kind}_torque_diff_max_baseline_piqp_ticks_nm"] = float(
            du[base_piqp].max()) if base_piqp.any() else 0.0
        # before the baseline's first piqp tick, both solve the same QPs exactly: the floor
        # of a change in floating-point order (cond(P) ~ 2e11); after it, piqp's error enters
        # the next ticks through the torque-change penalty
        first = int(np.argmax(base_piqp)) if base_piqp.any() else len(du)
        out[f"{kind}_torque_diff_max_before_first_piqp_nm"] = float(
            du[:first].max()) if first else 0.0
        out[f"{kind}_torque_diff_median_before_first_piqp_nm"] = float(
            np.median(du[:first])) if first else 0.0
        out[f"{kind}_modes_equal"] = bool(np.array_equal(ub.mode, ut.mode))
        for what, label in (("tick", "wall"), ("tick_cpu", "cpu")):
            rows.append((f"{kind} {label} median / p99 / max", " -> ".join(
                " / ".join(f"{out[f'{kind}_{name}_{what}_{s}_ms']:.3f}"
                           for s in ("median", "p99", "max"))
                for name in ("baseline", "this")) + "  ({:.2f}x / {:.2f}x / {:.2f}x)".format(
                *(out[f"{kind}_{what}_{s}_speedup_ratio"] for s in ("median", "p99", "max")))))
        rows.append((f"{kind} ticks with piqp", "{} -> {}  ({:.1%} -> {:.1%})".format(
            out[f"{kind}_baseline_piqp_ticks"], out[f"{kind}_this_piqp_ticks"],
            out[f"{kind}_baseline_piqp_ratio"], out[f"{kind}_this_piqp_ratio"])))
        if f"{kind}_baseline_on_baseline_piqp_ticks_cpu_median_ms" in out:
            rows.append((f"{kind} cpu on the baseline's piqp ticks, median / p99", " -> ".join(
                "{:.3f} / {:.3f}".format(
                    out[f"{kind}_{name}_on_baseline_piqp_ticks_cpu_median_ms"],
                    out[f"{kind}_{name}_on_baseline_piqp_ticks_cpu_p99_ms"])
                for name in ("baseline", "this"))))
        rows.append((f"{kind} max |du| all / closed-form / baseline-piqp ticks (N m)",
                     "{:.2e} / {:.2e} / {:.2e}".format(
                         out[f"{kind}_torque_diff_max_nm"],
                         out[f"{kind}_torque_diff_max_closed_form_ticks_nm"],
                         out[f"{kind}_torque_diff_max_baseline_piqp_ticks_nm"])))
        rows.append((f"{kind} max / median |du| before the baseline's first piqp tick (N m)",
                     "{:.2e} / {:.2e} ({} ticks)".format(
                         out[f"{kind}_torque_diff_max_before_first_piqp_nm"],
                         out[f"{kind}_torque_diff_median_before_first_piqp_nm"], first)))
        rows.append((f"{kind} same mode every tick", out[f"{kind}_modes_equal"]))
    print_table(f"side by side: baseline {rev} -> this tree (ms, {repeats} interleaved "
                "repeats; ratio = baseline / this)", rows)
    return out


def tight_optimum(P: np.ndarray, c: np.ndarray, lo: np.ndarray, hi: np.ndarray,
                   G: np.ndarray) -> np.ndarray | None:
    """The QP min 1/2 x'Px + c'x, lo <= x <= hi, G x <= 0 by piqp converged to 1e-11 (None
    when it does not get there)."""
    import piqp

    s = piqp.DenseSolver()
    st = s.settings
    st.eps_abs = st.eps_rel = st.eps_duality_gap_abs = st.eps_duality_gap_rel = 1e-11
    st.max_iter = 500
    st.verbose = False
    s.setup(np.asfortranarray(P), c, None, None, np.asfortranarray(G), np.full(len(G), -np.inf),
            np.zeros(len(G)), lo, hi)
    return s.result.x.copy() if s.solve().value == 1 else None


def kkt_residual(P: np.ndarray, c: np.ndarray, lo: np.ndarray, hi: np.ndarray,
                 G: np.ndarray, x: np.ndarray) -> tuple[float, float, int]:
    """An optimality check of x independent of the solver that found it: (largest constraint
    violation, stationarity residual relative to the size of its terms, active constraints).
    The residual is P x + c + A' lam with lam >= 0 of the constraints active at x (within
    1e-7) from non-negative least squares: 0 at an exact optimum, up to rounding."""
    from scipy.optimize import nnls

    viol = max(float((lo - x).max()), float((x - hi).max()), float((G @ x).max()))
    n = len(x)
    eye = np.eye(n)
    act = [-eye[i] for i in range(n) if x[i] - lo[i] < 1e-7]
    act += [eye[i] for i in range(n) if hi[i] - x[i] < 1e-7]
    act += [g for g in G if g @ x > -1e-7]
    grad = P @ x + c
    scale = float((np.abs(P) @ np.abs(x) + np.abs(c)).max())
    if act:
        A = np.array(act)
        lam, _ = nnls(A.T, -grad)  # grad + A' lam = 0, lam >= 0
        grad = grad + A.T @ lam
    return viol, float(np.abs(grad).max()) / scale, len(act)


def _gap(P: np.ndarray, c: np.ndarray, x: np.ndarray, ref: np.ndarray) -> tuple[float, float]:
    """(largest torque difference N m, cost excess relative to the reference's cost)."""
    cost, cost_ref = 0.5 * x @ P @ x + c @ x, 0.5 * ref @ P @ ref + c @ ref
    return float(np.abs(x[:10] - ref[:10]).max()), float((cost - cost_ref) / abs(cost_ref))


def _versus_optimum(solved: list[tuple[np.ndarray, ...]], desc: str = "QPs vs optimum"
                    ) -> tuple[list[float], list[float], list[float], list[float]]:
    """For each solved QP (P, c, lo, hi, G, x): x's KKT residual, and where piqp converged
    tightly, the torque difference and cost excess against that optimum and its residual."""
    du, ex, kkt, kkt_ref = [], [], [], []
    with progress(len(solved), desc, unit="QP") as bar:  # untimed, and slow: a tight solve each
        for P, c, lo, hi, G, x in solved:
            kkt.append(kkt_residual(P, c, lo, hi, G, x)[1])
            ref = tight_optimum(P, c, lo, hi, G)
            if ref is not None:
                d, e = _gap(P, c, x, ref)
                du.append(d)
                ex.append(e)
                kkt_ref.append(kkt_residual(P, c, lo, hi, G, ref)[1])
            bar.update(1)
    return du, ex, kkt, kkt_ref


def optimality(runs: dict[str, list[tuple[float, np.ndarray, np.ndarray, Any, Any]]],
               baseline: Callable[[], Any] | None) -> dict[str, Any]:
    """Untimed: each QP answer against the optimum of the same QP found by a tightly
    converged piqp (1e-11). This tree: every tick (its ``OscQP.last_problem``). Baseline: the
    ticks it sent to piqp (its ``_Solver.solve`` is wrapped to record the problem), when its
    code has that shape. Torque differences and relative cost excess (< 0: cheaper than
    piqp's optimum, i.e. piqp stopped short)."""
    import importlib

    from processes.osc.controller import SAFE, OscController

    out: dict[str, Any] = {}
    rows: list[tuple[str, object]] = []
    for kind, states in runs.items():
        osc = OscController()
        solved: list[tuple[np.ndarray, ...]] = []
        for t, q, v, plan, cmd in states:
            _, dbg = osc.update(t, q, v, plan, cmd)
            if dbg.mode == SAFE or dbg.qp_status != 1:
                continue
            x = np.concatenate([osc.qp.u, osc.qp.lam[np.repeat(osc.stance, 3)]])
            solved.append((*osc.qp.last_problem(), x))
        du, ex, kkt, kkt_ref = _versus_optimum(solved, f"{kind} QPs vs optimum")
        out[f"{kind}_this_vs_optimum_ticks"] = len(du)
        out[f"{kind}_this_vs_optimum_torque_max_nm"] = float(max(du, default=0.0))
        out[f"{kind}_this_vs_optimum_cost_excess_max_ratio"] = float(max(ex, default=0.0))
        out[f"{kind}_this_kkt_residual_max_ratio"] = float(max(kkt, default=0.0))
        out[f"{kind}_tight_piqp_kkt_residual_max_ratio"] = float(max(kkt_ref, default=0.0))
        rows.append((f"{kind} this tree, {len(du)} ticks: max |u - u*| (N m), cost excess",
                     f"{out[f'{kind}_this_vs_optimum_torque_max_nm']:.2e}, "
                     f"{out[f'{kind}_this_vs_optimum_cost_excess_max_ratio']:.1e}"))
        rows.append((f"{kind} KKT residual max: this tree / tight piqp",
                     f"{out[f'{kind}_this_kkt_residual_max_ratio']:.1e} / "
                     f"{out[f'{kind}_tight_piqp_kkt_residual_max_ratio']:.1e}"))
        if baseline is None:
            continue
        try:
            bqp = importlib.import_module("baseline_osc.qp")
            solve = bqp._Solver.solve
        except (ImportError, AttributeError):
            continue  # another code shape: nothing to hook
        seen: list[tuple[np.ndarray, ...]] = []

        def hooked(self: Any, P: np.ndarray, c: np.ndarray, _solve: Any = solve,
                   _seen: list = seen) -> Any:
            status, iters, x = _solve(self, P, c)
            if status == 1:
                _seen.append((np.array(P), c.copy(), self.x_l.copy(), self.x_u.copy(),
                              np.array(self.G), x.copy()))
            return status, iters, x

        bqp._Solver.solve = hooked
        try:
            _replay(states, baseline, f"{kind} baseline QPs")
        finally:
            bqp._Solver.solve = solve
        du, ex, kkt, _ = _versus_optimum(seen, f"{kind} baseline QPs vs optimum")
        out[f"{kind}_baseline_piqp_vs_optimum_ticks"] = len(du)
        if du:
            out[f"{kind}_baseline_piqp_vs_optimum_torque_median_nm"] = float(np.median(du))
            out[f"{kind}_baseline_piqp_vs_optimum_torque_max_nm"] = float(max(du))
            out[f"{kind}_baseline_piqp_vs_optimum_cost_excess_max_ratio"] = float(max(ex))
            out[f"{kind}_baseline_piqp_kkt_residual_max_ratio"] = float(max(kkt))
            rows.append((f"{kind} baseline piqp, {len(du)} ticks: |u - u*| median / max (N m),"
                         " cost excess max, KKT residual max",
                         f"{np.median(du):.2e} / {max(du):.2e}, {max(ex):.1e}, {max(kkt):.1e}"))
    print_table("QP answers against the QP's optimum (piqp converged to 1e-11), untimed", rows)
    return out


def main(argv: list[str] | None = None) -> int:
    """Record standing and walking states, replay them, print and optionally save figures."""
    ap = argparse.ArgumentParser(prog="cassie bench osc", description=__doc__)
    ap.add_argument("--json", default=None, help="write the figures to this JSON file")
    ap.add_argument("--ticks", type=int, default=4000,
                    help="ticks recorded per run (2 kHz: 4000 = 2 s of sim time)")
    ap.add_argument("--baseline", metavar="REV", default=None,
                    help="also time the OSC of git revision REV on the same states, "
                         "interleaved with this tree's, and compare their torques (a "
                         "revision with numba kernels compiles them first, ~12 s)")
    ap.add_argument("--repeats", type=int, default=3,
                    help="interleaved repeats of each version with --baseline (default 3)")
    ap.add_argument("--optimality", action="store_true",
                    help="also check (untimed) every QP answer against the optimum of the "
                         "same QP from a tightly converged piqp, this tree's and, with "
                         "--baseline, the baseline's piqp answers")
    args = ap.parse_args(argv)

    baseline = baseline_controller(args.baseline) if args.baseline else None  # fail early
    figures: dict[str, Any] = {"ticks_per_run": args.ticks, "deadline_ms": DEADLINE_MS,
                               "load_average_1min_start": os.getloadavg()[0]}
    all_ticks, all_cpu = [], []
    runs = {}
    for kind in ("standing", "walking"):
        states = runs[kind] = _record(kind, args.ticks)
        r = _replay(states, desc=f"replay {kind}")
        all_ticks.append(r.tick)
        all_cpu.append(r.cpu)
        figures.update(summarize(r.tick, f"{kind}_tick"))
        figures.update(summarize(r.cpu, f"{kind}_tick_cpu"))
        figures.update(summarize(r.solve, f"{kind}_solve"))
        figures[f"{kind}_qp_iterations_median"] = float(np.median(r.iters))
        # ticks solved in closed form (piqp skipped)
        figures[f"{kind}_unconstrained_ratio"] = float(np.mean(r.iters == 0))
        figures[f"{kind}_deadline_miss_ratio"] = float(np.mean(r.tick > DEADLINE_MS))
        figures[f"{kind}_recorded_s"] = len(states) * 0.0005
    tick = np.concatenate(all_ticks)
    figures.update(summarize(tick, "tick"))
    figures.update(summarize(np.concatenate(all_cpu), "tick_cpu"))
    figures["deadline_miss_ratio"] = float(np.mean(tick > DEADLINE_MS))
    figures["load_average_1min"] = os.getloadavg()[0]  # other work sharing the 2 cores

    rows = [(k, v) for k, v in figures.items() if not k.endswith("_count")]
    print_table("OSC tick (build + solve), ms", rows)
    if baseline is not None:
        figures.update(side_by_side(runs, baseline, args.baseline, args.repeats))
        figures["load_average_1min_end"] = os.getloadavg()[0]
        print(f"\nload average (1 min): {figures['load_average_1min_start']:.2f} at the start, "
              f"{figures['load_average_1min_end']:.2f} at the end")
    if args.optimality:
        figures.update(optimality(runs, baseline))
    write_json(args.json, "osc", figures)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
