"""`cassie bench osc`: OSC tick time (build + solve of the QP (14)) on recorded robot states.

States are recorded first from closed-loop MuJoCo runs at 2 kHz in lockstep: a standing run,
then a walking run (standing hand-over, then walking at 0.375 m/s on the plans of the MPFC
node of ``hw_config/sim.yaml``, solved at 200 Hz on the true state). A fresh controller then
replays each recording in order, and every ``update`` call is timed (wall clock), with piqp's
share measured separately. The collector is disabled during the timed loops, as the live OSC
loop does. Figures are printed and optionally written as flat JSON; nothing is asserted.
"""

from __future__ import annotations

import argparse
import gc
import os
import time
from typing import Any

import numpy as np

from tools.benchmarks.common import DirectInbox, print_table, summarize, write_json

DEADLINE_MS = 1.0


class _Published:
    """The MPFC node's context for a direct call: keeps the last message of each output."""

    def __init__(self) -> None:
        self.out: dict[str, Any] = {}

    def due(self, role: str) -> bool:  # no decimation outside the runners

        return True


    def publish(self, role: str, msg: Any) -> None:
        self.out[role] = msg


def _record(kind: str, ticks: int) -> list[tuple[float, np.ndarray, np.ndarray, Any, Any]]:
    """Run the OSC closed loop in MuJoCo and keep (t, q, v, plan, command) of every tick."""
    import mujoco

    from lcmtypes import command_t, robot_state_t
    from processes.mpfc.process import make_node
    from processes.osc.controller import SAFE, OscController
    from processes.osc.model import load_cassie, standing_pose
    from runtime.config import HW_CONFIG_DIR, load_profile

    m = load_cassie()
    m.opt.impratio = 10.0
    d = mujoco.MjData(m)
    d.qpos[:] = standing_pose(m)
    mujoco.mj_forward(m, d)
    osc = OscController()
    profile = load_profile(HW_CONFIG_DIR / "sim.yaml")
    mpfc = make_node(profile.processes["mpfc"], profile)
    ctx, inbox = _Published(), DirectInbox("state")
    cmd = command_t()
    cmd.mode = 1
    cmd.vx = 0.375
    plan = None
    out: list[tuple[float, np.ndarray, np.ndarray, Any, Any]] = []
    for k in range(ticks):
        t = float(d.time)
        if kind == "walking" and t >= 0.25:
            cmd.mode = 0
            if k % 10 == 0:  # the MPFC at 200 Hz, on the true state
                s = robot_state_t()
                s.header.utime = round(t * 1e6)
                s.num_positions, s.num_velocities = m.nq, m.nv
                s.q, s.v = d.qpos.tolist(), d.qvel.tolist()
                inbox.messages["state"], inbox.messages["command"] = s, cmd
                mpfc.tick(ctx, inbox)
                plan = ctx.out["plan"]
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
    return out


def _replay(states: list[tuple[float, np.ndarray, np.ndarray, Any, Any]]
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Time every tick of a fresh controller on the recorded states (ms): wall clock, and
    this thread's CPU time (which a busy shared machine inflates much less)."""
    from processes.osc.controller import OscController

    osc = OscController()
    n = len(states)
    tick, cpu, solve, iters = np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n)
    gc.collect()
    gc.disable()
    try:
        for i, (t, q, v, plan, cmd) in enumerate(states):
            c0 = time.thread_time()
            t0 = time.perf_counter()
            _, dbg = osc.update(t, q, v, plan, cmd)
            tick[i] = (time.perf_counter() - t0) * 1e3
            cpu[i] = (time.thread_time() - c0) * 1e3
            solve[i] = dbg.solve_ms
            iters[i] = dbg.qp_iterations
    finally:
        gc.enable()
    return tick, cpu, solve, iters


def main(argv: list[str] | None = None) -> int:
    """Record standing and walking states, replay them, print and optionally save figures."""
    ap = argparse.ArgumentParser(prog="cassie bench osc", description=__doc__)
    ap.add_argument("--json", default=None, help="write the figures to this JSON file")
    ap.add_argument("--ticks", type=int, default=4000,
                    help="ticks recorded per run (2 kHz: 4000 = 2 s of sim time)")
    args = ap.parse_args(argv)

    figures: dict[str, Any] = {"ticks_per_run": args.ticks, "deadline_ms": DEADLINE_MS}
    all_ticks, all_cpu = [], []
    for kind in ("standing", "walking"):
        states = _record(kind, args.ticks)
        tick, cpu, solve, iters = _replay(states)
        all_ticks.append(tick)
        all_cpu.append(cpu)
        figures.update(summarize(tick, f"{kind}_tick"))
        figures.update(summarize(cpu, f"{kind}_tick_cpu"))
        figures.update(summarize(solve, f"{kind}_solve"))
        figures[f"{kind}_qp_iterations_median"] = float(np.median(iters))
        # ticks where the unconstrained minimiser was feasible and piqp was skipped
        figures[f"{kind}_unconstrained_ratio"] = float(np.mean(iters == 0))
        figures[f"{kind}_deadline_miss_ratio"] = float(np.mean(tick > DEADLINE_MS))
        figures[f"{kind}_recorded_s"] = len(states) * 0.0005
    tick = np.concatenate(all_ticks)
    figures.update(summarize(tick, "tick"))
    figures.update(summarize(np.concatenate(all_cpu), "tick_cpu"))
    figures["deadline_miss_ratio"] = float(np.mean(tick > DEADLINE_MS))
    figures["load_average_1min"] = os.getloadavg()[0]  # other work sharing the 2 cores

    rows = [(k, v) for k, v in figures.items() if not k.endswith("_count")]
    print_table("OSC tick (build + solve), ms", rows)
    write_json(args.json, "osc", figures)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
