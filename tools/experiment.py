"""`cassie experiment NAME`: a closed-loop walking experiment in the deterministic harness.

The same process nodes as `cassie launch` (from ``hw_config/experiment.yaml``) are stepped in
sim-time order inside this one process, so a result depends on the seed and the code, never on
how busy the machine is. Terrains: ``flat``, ``stairs`` (15 cm rise, 27 cm depth; 40 cm with
``--perception``, as the paper's Fig. 11), ``beam``
(23 cm wide) and ``stones`` (the paper's random stepping stones, Table I, ``--dmin D``), with
ground-truth footholds from the sim, or with ``--perception`` the footholds of S3.

Reported per trial, from the sim's ground truth: distance walked, mean forward speed against the
command, falls (pelvis below 0.6 m over the terrain under it), footsteps (touchdowns) and
footsteps outside every foothold, and whether the trial succeeded (no fall, speed within 15% of
the command, no footstep outside a foothold).
"""

from __future__ import annotations

import argparse
import math
import os
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from lcmtypes import command_t, ground_truth_t, robot_state_t
from runtime.cassie_packets import STATUS_HOLDER_ENGAGED
from runtime.config import HW_CONFIG_DIR, load_profile, safe_load
from runtime.config_types import Profile
from runtime.harness import Binding, Harness
from runtime.node import Node
from runtime.scheduling import pin_to_supervisor_host
from tools.benchmarks.common import print_table, progress, write_json
from tools.report import analyse, load_budgets, print_cpu, print_loops, print_realtime

EXPERIMENTS = ("flat", "stairs", "beam", "stones")
FALL_HEIGHT_M = 0.6
MIN_SWING_S = 0.1  # shorter airborne spells are contact flicker, not steps
HEADING_GAIN = 1.0  # operator's yaw rate per radian of heading error (Section VIII-A)
SPEED_TOLERANCE = 0.15


@dataclass
class Trial:
    """Figures of one trial; names carry their unit."""

    experiment: str
    seed: int
    duration_s: float = 0.0
    distance_m: float = 0.0
    mean_velocity_mps: float = 0.0
    commanded_velocity_mps: float = 0.0
    velocity_error_ratio: float = 0.0
    fell: bool = False
    fall_time_s: float = -1.0
    min_pelvis_height_m: float = 0.0
    footsteps: int = 0
    footsteps_outside: int = 0
    success: bool = False
    wall_s: float = 0.0
    mode: str = "harness"  # harness (deterministic, one process), lockstep or realtime (launch)
    timing: dict[str, dict[str, Any]] = field(default_factory=dict)  # live runs: report's loops
    cpu: dict[str, Any] = field(default_factory=dict)  # live runs: the report's CPU table
    realtime: dict[str, Any] = field(default_factory=dict)  # live runs: real-time checks
    notes: list[str] = field(default_factory=list)


class Operator(Node):
    """The operator's radio in the harness: the commanded speed, and a yaw rate proportional
    to the heading error (as the paper's simulation experiments command the OSC)."""

    name = "operator"
    inputs = {"ground_truth": ground_truth_t}
    outputs = {"command": command_t}

    def __init__(self, vx: float) -> None:
        self.vx = vx
        self.period_s = 0.05  # 20 Hz, as a radio sends

    def command(self, utime: int, gt: Any | None) -> command_t:
        """The radio's message: walk at ``vx``, turning back to heading 0."""
        cmd = command_t()
        cmd.header.utime = utime
        cmd.vx = self.vx
        if gt is not None:
            w, x, y, z = gt.q[3:7]
            yaw = float(np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z)))
            cmd.yaw_rate = -HEADING_GAIN * yaw
        return cmd

    def tick(self, ctx: Any, inbox: Any) -> None:
        ctx.publish("command", self.command(ctx.now_utime, inbox.latest("ground_truth")))


class Judge:
    """Watches GROUND_TRUTH: falls, distance, speed and where each foot touches down."""

    def __init__(self, footholds: list[Any], walk_start_s: float,
                 ground: Callable[[float, float], float] | None = None) -> None:
        self.footholds = footholds
        self.walk_start_s = walk_start_s
        #: height of the terrain under (x, y): a fall is the pelvis below FALL_HEIGHT_M over
        #: it (on stairs a robot lying on the landing has its pelvis above 0.6 m)
        self.ground = ground if ground is not None else (lambda x, y: 0.0)
        self.x0: float | None = None
        self.x_last = 0.0
        self.t_last = 0.0
        self.min_z = np.inf
        self.fall_t: float | None = None
        self.prev_contact = [True, True]
        self.lift_t = [-1.0, -1.0]  # when each foot last left the ground
        self.touchdowns: list[tuple[float, np.ndarray]] = []

    def __call__(self, t_us: int, gt: Any) -> None:
        t = gt.header.utime * 1e-6
        z = gt.q[2] - self.ground(gt.q[0], gt.q[1])
        self.min_z = min(self.min_z, z)
        if z < FALL_HEIGHT_M and self.fall_t is None:
            self.fall_t = t
        if t >= self.walk_start_s:
            if self.x0 is None:
                self.x0 = gt.q[0]
                self.t0 = t
            self.x_last, self.t_last = gt.q[0], t
            for i in (0, 1):
                if not gt.foot_contact[i] and self.prev_contact[i]:
                    self.lift_t[i] = t
                # a touchdown ends a real swing (airborne for MIN_SWING_S), not a contact flicker
                if (
                    gt.foot_contact[i]
                    and not self.prev_contact[i]
                    and self.lift_t[i] >= 0
                    and t - self.lift_t[i] >= MIN_SWING_S
                ):
                    self.touchdowns.append((t, np.asarray(gt.foot_pos[i], dtype=float)))
        self.prev_contact = list(gt.foot_contact)

    def outside(self) -> int:
        if not self.footholds:
            return 0
        return sum(
            not any(f.contains_xy(p[0], p[1]) for f in self.footholds) for _, p in self.touchdowns
        )


#: tread depth of ``cassie experiment stairs --perception`` (the paper's Fig. 11, bottom)
PERCEPTION_STAIRS_DEPTH_M = 0.40


def _terrain_file(name: str, dmin: float | None, seed: int, work: Path,
                  depth: float | None = None) -> str:
    if name == "stairs" and depth is not None:
        # hw_config/terrains/stairs.yaml with another tread depth (Fig. 11: 27 cm with ground
        # truth, 40 cm with perception)
        doc = safe_load((HW_CONFIG_DIR / "terrains" / "stairs.yaml").read_text())
        doc["params"]["depth"] = float(depth)
        path = work / "stairs.yaml"
        path.write_text(yaml.safe_dump(doc, sort_keys=False))
        return str(path)
    if name == "stones":
        path = work / "stones.yaml"
        path.write_text(
            "terrain: stones\n"
            f"seed: {seed}\nfoothold_margin: 0.02\nfoot_half_size: [0.10, 0.02]\n"
            f"params: {{d_min: {dmin if dmin is not None else 0.35}, platform: 1.0,"
            " pit_depth: 0.5}\n"
        )
        return str(path)
    return str(HW_CONFIG_DIR / "terrains" / f"{name}.yaml")


def _write_profile(base_profile: Path, name: str, terrain: str, perception: bool, work: Path,
                   mode: str | None = None) -> tuple[Path, list[str]]:
    """The experiment's profile: the base one on ``terrain``, perception joining or not."""
    base = load_profile(base_profile)
    launch = [p for p in base.launch if perception or p not in ("perception", "s3")]
    if perception:
        launch += [p for p in ("perception", "s3") if p not in launch]
    sim_params: dict[str, Any] = {"terrain": terrain, "publish_footholds": not perception}
    # depth frames only feed perception; with it, rendered inline in the harness (sim-time
    # order, deterministic), as configured otherwise
    sim_params["camera_render"] = "off" if not perception else ("auto" if mode else "inline")
    doc: dict[str, Any] = {"include": [str(base_profile)], "profile": f"experiment_{name}"}
    if mode:
        doc["mode"] = mode
    doc["launch"] = launch
    doc["overrides"] = {"sim": {"params": sim_params},
                        "mpfc": {"params": {"footholds": "channel"}}}
    prof_path = work / "experiment.yaml"
    prof_path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return prof_path, launch


def _prepare(base_profile: Path, name: str, dmin: float | None, seed: int, perception: bool,
             work: Path, mode: str | None = None, depth: float | None = None
             ) -> tuple[Path, Profile, list[str], list[Any], Callable[[float, float], float]]:
    """The trial's terrain and profile in ``work``: (profile path, profile, launched
    processes, the terrain's ground-truth footholds for the judge, its height)."""
    from sim import terrain as terrain_mod

    terrain = _terrain_file(name, dmin, seed, work, depth)
    prof_path, launch = _write_profile(base_profile, name, terrain, perception, work, mode)
    # a footstep is judged on the faces (less the margin), not on the footholds shrunk for
    # the foot that the controller aims within
    ter = terrain_mod.load_terrain(terrain)
    footholds = list(ter.landing_surfaces)
    return prof_path, load_profile(prof_path), launch, footholds, ter.height_at


def run_trial(
    name: str,
    duration_s: float,
    seed: int,
    dmin: float | None,
    perception: bool,
    vx: float,
    base_profile: Path,
    setup: Callable[[Harness], None] | None = None,
    depth: float | None = None,
) -> Trial:
    """One trial: build the experiment profile's nodes, run, judge. ``setup`` may look at
    (or instrument) the harness's nodes before the run; ``depth`` is the stairs' tread depth
    (None: hw_config/terrains/stairs.yaml's)."""
    trial = Trial(experiment=name, seed=seed, commanded_velocity_mps=vx)
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        _, profile, launch, footholds, ground = _prepare(base_profile, name, dmin, seed,
                                                         perception, work, depth=depth)
        h = Harness.from_profile(profile)
        gt_channel = profile.channels["ground_truth"].name
        h.add(
            Binding(
                Operator(vx),
                inputs={"ground_truth": gt_channel},
                outputs={"command": profile.channels["command"].name},
            )
        )
        judge = Judge(footholds, walk_start_s=0.0, ground=ground)
        h.tap(gt_channel, judge)
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
            while t_us < end_us and judge.fall_t is None:
                nxt = min(t_us + step_us, end_us)
                h.run_until(nxt, stop=lambda: judge.fall_t is not None)
                bar.update((nxt - t_us) / 1e6)
                t_us = nxt
        trial.wall_s = time.perf_counter() - t0
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
    depth: float | None = None,
    dashboard: bool = False,
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
        prof_path, profile, launch, footholds, ground = _prepare(base_profile, name, dmin,
                                                                 seed, perception, work, mode,
                                                                 depth)
        # the trial starts when the sim releases the holder (the OSC's first torque): the
        # processes take seconds to start while the sim already runs
        judge = Judge(footholds, math.inf, ground)
        operator = Operator(vx)
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

        bus.subscribe_raw(f"^{profile.channels['ground_truth'].name}$", on_gt)
        bus.subscribe_raw(f"^{profile.channels['network_state'].name}$", on_state)
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


def _verdict(trial: Trial, judge: Judge, launch: list[str]) -> Trial:
    """Fill the trial's figures from what the judge saw."""
    vx = trial.commanded_velocity_mps
    trial.duration_s = judge.t_last
    trial.fell = judge.fall_t is not None
    trial.fall_time_s = judge.fall_t if judge.fall_t is not None else -1.0
    trial.min_pelvis_height_m = float(judge.min_z)
    if judge.x0 is not None:
        trial.distance_m = float(judge.x_last - judge.x0)
        span = judge.t_last - judge.t0
        trial.mean_velocity_mps = trial.distance_m / span if span > 0 else 0.0
    trial.velocity_error_ratio = (abs(trial.mean_velocity_mps - vx) / abs(vx)) if vx else 0.0
    trial.footsteps = len(judge.touchdowns)
    trial.footsteps_outside = judge.outside()
    trial.success = (
        not trial.fell
        and trial.velocity_error_ratio <= SPEED_TOLERANCE
        and trial.footsteps_outside == 0
        and trial.footsteps > 0
    )
    if "osc" not in launch:
        trial.notes.append("no walking controller in the experiment profile")
    return trial


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="cassie experiment",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    ap.add_argument("name", choices=EXPERIMENTS)
    ap.add_argument("--duration", type=float, default=10.0, help="sim seconds per trial")
    ap.add_argument("--seed", type=int, default=0, help="terrain seed (stones)")
    ap.add_argument("--trials", type=int, default=1, help="trials, seeds seed..seed+N-1")
    ap.add_argument("--dmin", type=float, default=None, help="stones: minimum side d_min, m")
    ap.add_argument("--depth", type=float, default=None,
                    help="stairs: tread depth, m (default 0.27 with true footholds and 0.40 "
                    "with --perception: the paper's Fig. 11, top and bottom)")
    ap.add_argument("--perception", action="store_true", help="S3 footholds, not ground truth")
    ap.add_argument("--vx", type=float, default=0.375, help="commanded speed, m/s")
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
    args = ap.parse_args(argv)
    if args.dmin is not None and args.name != "stones":
        ap.error("--dmin is for the stones experiment")
    if args.depth is not None and (args.name != "stairs" or not 0.1 <= args.depth <= 2.0):
        ap.error("--depth is for the stairs experiment, 0.1 to 2.0 m")
    if args.duration <= 0 or args.trials < 1:
        ap.error("--duration must be > 0 and --trials >= 1")
    if args.name == "stairs" and args.perception and args.depth is None:
        # S3's safety margins leave no steppable band on 27 cm treads; the paper's perceptive
        # stairs are 40 cm deep (Section VIII-A, Fig. 11 bottom)
        args.depth = PERCEPTION_STAIRS_DEPTH_M
        print(f"stairs with perception: {args.depth:.2f} m treads, as the paper's Fig. 11 "
              "(--depth to change)")
    if args.launch:
        base = args.profile if args.profile != HW_CONFIG_DIR / "experiment.yaml" else (
            HW_CONFIG_DIR / "sim.yaml")
        trials = [
            run_live_trial(args.name, args.duration, args.seed + i, args.dmin, args.perception,
                           args.vx, args.launch, base,
                           args.log_dir / f"trial{i}" if args.log_dir else None, args.depth,
                           args.dashboard)
            for i in range(args.trials)
        ]
    else:
        trials = [
            run_trial(args.name, args.duration, args.seed + i, args.dmin, args.perception,
                      args.vx, args.profile, depth=args.depth)
            for i in range(args.trials)
        ]
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
        + (" with perception" if args.perception else " with true footholds"),
        "trials": len(trials),
        "success_ratio": ok / len(trials),
        "falls": sum(t.fell for t in trials),
        "distance_m": float(np.mean([t.distance_m for t in trials])),
        "mean_velocity_mps": float(np.mean([t.mean_velocity_mps for t in trials])),
        "commanded_velocity_mps": args.vx,
        "footsteps": sum(t.footsteps for t in trials),
        "footsteps_outside": sum(t.footsteps_outside for t in trials),
        "sim_duration_s": args.duration,
    }
    if args.dmin is not None:
        figures["dmin_m"] = args.dmin
    if args.depth is not None:
        figures["stair_depth_m"] = args.depth
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


if __name__ == "__main__":
    sys.exit(main())
