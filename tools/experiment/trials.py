"""Running one trial: in the deterministic harness (``run_trial``) or with the real
multi-process stack launched in lockstep or real time (``run_live_trial``)."""

from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from lcmtypes import ground_truth_t, mpfc_output_t, robot_state_t
from runtime.cassie_packets import STATUS_HOLDER_ENGAGED
from runtime.config import HW_CONFIG_DIR
from runtime.harness import Binding, Harness
from runtime.scheduling import pin_to_supervisor_host
from tools.benchmarks.common import progress
from tools.experiment.courses import GUIDE_PROCESS, _prepare
from tools.experiment.judge import Judge, Trial, _verdict
from tools.experiment.operator import LATERAL_GAIN, Operator
from tools.report import analyse, load_budgets

#: a trial whose robot has not taken a step and has stood this long in a stop for nothing
#: ahead ends there: standing, nothing changes (the map, the footholds), and a perception
#: sweep's small stones (none left after S3's erosion) spent 20 s of sim each on it
STOOD_STILL_END_S = 5.0


def guide_note(node: Any, sim_s: float) -> str:
    """The SLIP guide's figures of a harness trial: plans, their rate in sim time, their
    wall times (median, max) and QPs."""
    c = node.counters()
    ms = list(getattr(node, "plan_ms", ()))
    plans, fails = int(c.get("plans", 0)), int(c.get("failures", 0))
    rate = (plans + fails) / sim_s if sim_s > 0 else 0.0
    times = (f"plan wall median {float(np.median(ms)):.0f} ms, max {max(ms):.0f} ms, "
             f"{c.get('qp_solves', 0) / max(plans, 1):.1f} QPs a plan" if ms else "no plan")
    return (f"guide: {plans} plans and {fails} without one in {sim_s:.1f} s of sim "
            f"({rate:.1f} Hz); {times}; last: {node.last_status}")


def guided_note(c: Any) -> str:
    """The MPFC's solves the guide guided, narrowed, or left with every foothold."""
    return (f"MPFC: {int(c['guided'])} of {int(c['solves'])} solves guided, "
            f"{int(c.get('guide_narrowed', 0))} on fewer footholds, "
            f"{int(c.get('guide_fallbacks', 0))} with none left by the narrowing (all kept)")


def _stood_still(planner: Any, t: float, judge: Judge) -> bool:
    c = planner.counters()
    since = float(c.get("halt_since_s", -1.0))
    return (bool(c.get("halted", 0)) and since >= 0.0 and not judge.touchdowns
            and t - since >= STOOD_STILL_END_S)


def run_trial(
    name: str,
    duration_s: float,
    seed: int,
    dmin: float | None,
    perception: bool,
    vx: float,
    base_profile: Path,
    setup: Callable[[Harness], None] | None = None,
    size: float | None = None,
    fixed_timing: bool = False,
    lateral_gain: float = LATERAL_GAIN,
    true_state: bool = False,
    planner: str = "mpfc",
    segmenter: str = "s3",
    guide: bool = False,
) -> Trial:
    """One trial: build the experiment profile's nodes, run, judge. ``setup`` may look at
    (or instrument) the harness's nodes before the run; ``size`` is the stairs' tread depth,
    the beam's width or the chasm's (None: its terrain file's); ``guide``: the SLIP guide
    runs and the MPFC follows it (its plans and their times in the trial's notes)."""
    trial = Trial(experiment=name, seed=seed, commanded_velocity_mps=vx)
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        _, profile, launch, footholds, ground, goal, path = _prepare(
            base_profile, name, dmin, seed, perception, work, size=size,
            fixed_timing=fixed_timing, true_state=true_state, planner=planner,
            segmenter=segmenter, guide=guide)
        h = Harness.from_profile(profile)
        gt_channel = profile.channels["ground_truth"].name
        h.add(
            Binding(
                Operator(vx, lateral_gain, path=path),
                inputs={"ground_truth": gt_channel},
                outputs={"command": profile.channels["command"].name},
            )
        )
        judge = Judge(footholds, walk_start_s=0.0, ground=ground, goal_x=goal)
        h.tap(gt_channel, judge)
        h.tap(profile.channels["plan"].name, judge.on_plan)
        if setup is not None:
            setup(h)
        t0 = time.perf_counter()
        # in half-second steps of sim time, with a progress bar and an ETA on a terminal
        # (tqdm: off by itself when stderr is not one)
        from tqdm import tqdm

        end_us, step_us = int(duration_s * 1e6), 500_000
        with tqdm(total=round(duration_s, 1), unit="sim s", desc=f"{name} seed {seed}",
                  disable=None, leave=False, bar_format="{l_bar}{bar}| {n:.1f}/{total} sim s "
                  "[{elapsed}<{remaining}]") as bar:
            t_us = 0
            planner = next((b.node for b in h.bindings if b.node.name == "mpfc"), None)
            while t_us < end_us and not judge.finished():
                nxt = min(t_us + step_us, end_us)
                h.run_until(nxt, stop=judge.finished)
                bar.update((nxt - t_us) / 1e6)
                t_us = nxt
                if planner is not None and _stood_still(planner, t_us * 1e-6, judge):
                    trial.notes.append(f"stood still {STOOD_STILL_END_S:g} s in a stop for "
                                       f"nothing ahead, on the ground it started on: ended "
                                       f"at {t_us * 1e-6:.1f} s")
                    break
        trial.wall_s = time.perf_counter() - t0
        for b in h.bindings:
            if b.node.name == "mpfc":
                c = b.node.counters()
                trial.halts = int(c.get("halts", 0))
                trial.halted_at_end = bool(c.get("halted", 0))
                trial.halt_s = float(c.get("halt_since_s", -1.0))
                if trial.halt_s >= 0.0:
                    trial.halt_speed_mps = judge.speed_at(trial.halt_s)
                    trial.halt_feet_on_footholds = judge.feet_on_footholds_at(trial.halt_s)
                hx, hy = float(c.get("halt_x", math.nan)), float(c.get("halt_y", math.nan))
                if math.isfinite(hx):  # the stop began with the stance foot on the course?
                    trial.halt_on_foothold = judge.on_foothold(hx, hy)
                if c.get("guided"):
                    trial.notes.append(guided_note(c))
            elif b.node.name == GUIDE_PROCESS:
                trial.notes.append(guide_note(b.node, judge.t_last))
        h.close()
    return _verdict(trial, judge, launch)


def run_live_trial(
    name: str,
    duration_s: float,
    seed: int,
    dmin: float | None,
    perception: bool,
    vx: float,
    mode: str,
    base_profile: Path = HW_CONFIG_DIR / "sim.yaml",
    log_dir: Path | None = None,
    size: float | None = None,
    dashboard: bool = False,
    fixed_timing: bool = False,
    lateral_gain: float = LATERAL_GAIN,
    true_state: bool = False,
    planner: str = "mpfc",
    segmenter: str = "s3",
    guide: bool = False,
) -> Trial:
    """One trial with the real multi-process stack: ``cassie launch`` of the base profile in
    ``mode`` (lockstep or realtime) under the supervisor, every message logged; this process
    is the operator's radio and the judge, on the bus. Timing comes from the log afterwards."""
    from runtime.bus import Bus

    trial = Trial(experiment=name, seed=seed, commanded_velocity_mps=vx, mode=mode)
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        logs = log_dir if log_dir is not None else work / "logs"
        logs.mkdir(parents=True, exist_ok=True)
        prof_path, profile, launch, footholds, ground, goal, path = _prepare(
            base_profile, name, dmin, seed, perception, work, mode, size, fixed_timing,
            true_state, planner, segmenter, guide)
        # the trial starts when the sim releases the holder (the OSC's first torque): the
        # processes take seconds to start while the sim already runs
        judge = Judge(footholds, math.inf, ground, goal)
        operator = Operator(vx, lateral_gain, path=path)
        # this process is the operator's radio and the judge: a laptop tool, on its CPUs (as
        # the supervisor), never on the NUC's, and its CPU goes into the table as a watcher's
        pin_to_supervisor_host(profile)
        bus = Bus(profile.lcm_url, source="operator")
        newest: list[Any] = [None]

        def on_gt(_channel: str, data: bytes) -> None:
            try:
                gt = ground_truth_t.decode(data)
            except (ValueError, KeyError):
                return
            newest[0] = gt
            judge(0, gt)

        def on_state(_channel: str, data: bytes) -> None:
            if not math.isinf(judge.walk_start_s):
                return
            try:
                st = robot_state_t.decode(data)
            except (ValueError, KeyError):
                return
            if not st.target_status & STATUS_HOLDER_ENGAGED:
                judge.walk_start_s = st.header.utime * 1e-6

        def on_plan(_channel: str, data: bytes) -> None:
            try:
                judge.on_plan(0, mpfc_output_t.decode(data))
            except (ValueError, KeyError):
                return

        bus.subscribe_raw(f"^{profile.channels['ground_truth'].name}$", on_gt)
        bus.subscribe_raw(f"^{profile.channels['network_state'].name}$", on_state)
        bus.subscribe_raw(f"^{profile.channels['plan'].name}$", on_plan)
        cmd_channel = profile.channels["command"].name
        out = (logs / "supervisor.txt").open("w")
        sup = subprocess.Popen(
            [sys.executable, "-m", "tools.cli", "launch", str(prof_path), "--no-live", "--log",
             "--log-dir", str(logs), *(["--dashboard"] if dashboard else [])],
            stdout=out, stderr=subprocess.STDOUT, start_new_session=True,
        )
        # sim time runs at most at wall-clock speed; lockstep on 2 busy cores is much slower
        wall_limit = 120.0 + duration_s * (60.0 if mode == "lockstep" else 4.0)
        t0 = time.perf_counter()
        next_cmd = t0
        cpu0 = time.process_time()
        # the seconds walked since the holder let go, with an ETA, on a terminal (redrawn
        # at most twice a second: this process's CPU is in the run's CPU table)
        bar = progress(round(duration_s, 1), f"{name} seed {seed}, {mode}", unit="sim s",
                       bar_format="{l_bar}{bar}| {n:.1f}/{total} sim s walked "
                                  "[{elapsed}<{remaining}]")
        try:
            while sup.poll() is None and time.perf_counter() - t0 < wall_limit:
                bus.poll_every(0.01)  # a watcher: batched reads
                now = time.perf_counter()
                if now >= next_cmd:
                    gt = newest[0]
                    utime = gt.header.utime if gt is not None else 0
                    bus.publish(cmd_channel, operator.command(utime, gt))
                    next_cmd = now + operator.period_s
                walked = judge.t_last - judge.walk_start_s  # (-inf until the release)
                # (an update of 0 too: it keeps the elapsed time moving while the stack starts)
                bar.update(max(min(walked, duration_s) - bar.n, 0.0))
                if judge.fall_t is not None or walked >= duration_s:
                    break
        finally:
            bar.close()
            trial.wall_s = time.perf_counter() - t0
            own_cpu_s = time.process_time() - cpu0
            if sup.poll() is None:
                sup.send_signal(signal.SIGINT)
                try:
                    sup.wait(30)
                except subprocess.TimeoutExpired:
                    os.killpg(sup.pid, signal.SIGKILL)
                    sup.wait()
            out.close()
            bus.close()
        walked = judge.t_last - judge.walk_start_s if judge.x0 is not None else 0.0
        if walked < duration_s and judge.fall_t is None:
            trial.notes.append(
                f"stopped after {walked:.2f} s of walking of {duration_s:g} s "
                f"(supervisor exit code {sup.returncode}, wall {trial.wall_s:.0f} s); "
                f"see {logs / 'supervisor.txt'}")
        log_file = logs / "lcm.log"
        if log_file.exists():
            rep = analyse(log_file, load_budgets(HW_CONFIG_DIR / "budgets.yaml"))
            trial.timing = rep["loops"]
            trial.cpu = rep["cpu"]
            _add_own_cpu(trial.cpu, own_cpu_s, trial.wall_s)
            trial.realtime = rep["realtime"]
        else:
            trial.notes.append("no LCM log was recorded: no timing summary")
    _verdict(trial, judge, launch)
    trial.duration_s = walked
    if walked < duration_s - 0.01 and judge.fall_t is None:
        trial.success = False
    return trial


def _add_own_cpu(cpu: dict[str, Any], cpu_s: float, wall_s: float) -> None:
    """This process (operator and judge, a watcher) as a row of the CPU table, in the total."""
    procs = cpu.get("processes")
    if procs is None or wall_s <= 0:
        return
    share = cpu_s / wall_s
    procs["experiment"] = {"source": "self", "cpu_s": cpu_s, "wall_s": wall_s,
                           "cpu_share": share, "cpu_per_sim_s": float("nan"),
                           "budget_share": float("nan"), "within_budget": True}
    cpu["total_share"] = cpu.get("total_share", 0.0) + share
    limit = cpu.get("total_budget", 0.0)
    cpu["within_budget"] = limit <= 0 or cpu["total_share"] <= limit


