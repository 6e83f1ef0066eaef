"""The OSC process shell: a ``Node`` that feeds robot states to ``OscController``.

Driven by each newest ``state`` (robot_state_t, CASSIE_STATE); reads the newest ``plan``
(mpfc_output_t) and ``command`` (command_t; until the first one arrives, ``params.start``:
``walk``, the default, or ``stand``); publishes ``torque`` (torque_command_t, joint-side
N m in actuator order) and ``debug`` (osc_debug_t), both stamped with the state's utime.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from lcmtypes import command_t, mpfc_output_t, osc_debug_t, robot_state_t, torque_command_t
from runtime.cassie_packets import STATUS_HOLDER_ENGAGED
from runtime.config_types import ProcessConfig, Profile
from runtime.node import HEALTH_FAULT, HEALTH_OK, HEALTH_WARNING, Context, Inbox, Node
from runtime.params import spec

from .controller import SAFE, OscController
from .fallback import PlanFallback
from .model import CassieModel
from .tasks import OscGains, OscParams
from .walking import STANDING as GAIT_STANDING

#: ticks of the set-up warm-up (0.5 ms each): standing, hand-over, single and double stance
WARM_UP_TICKS = 2000
START_MODES = ("walk", "stand")
#: ``torque_command_t.mode`` of the zero torques sent before the first plan (hold_until_plan)
OFF = 3


class OscNode(Node):
    """Operational space controller (Section III-E): state in, torques out."""

    name = "osc"
    inputs = {"state": robot_state_t, "plan": mpfc_output_t, "command": command_t}
    outputs = {"torque": torque_command_t, "debug": osc_debug_t}
    trigger_role = "state"
    trigger_policy = "newest"

    def __init__(self, params: OscParams, start: str = "walk",
                 hold_until_plan: bool = False, stand_first_s: float = 0.0,
                 soft_start_s: float = 0.0) -> None:
        self.params = params
        #: off (zero torque, mode 3: the start-up holder keeps the robot) until the MPFC's
        #: first plan: the robot is let go only once the footstep planner is up ...
        self._hold_until_plan = hold_until_plan
        #: ... and then stands this long (whatever the radio says) before it may walk: in the
        #: holder, which the bridge releases after its release_after_s of standing, then free
        self._stand_first_us = round(stand_first_s * 1e6)
        self._walk_from_us: int | None = None if stand_first_s > 0.0 else 0
        #: in the holder, the torques come on over this long from the first controlled tick
        self._soft_start_us = round(soft_start_s * 1e6)
        self._on_from_us: int | None = None
        self._first_state = True
        self._stand = command_t()
        self._stand.mode = 1
        #: until the radio's first command: walk (mode 0, no turning: the stack walks at the
        #: MPFC's default velocity out of the holder) or stand (wait for the radio)
        self._default_command: command_t | None = None
        if start == "walk":
            self._default_command = command_t()
            self._default_command.mode = 0
        self.controller: OscController | None = None
        self.fallback: PlanFallback | None = None
        self._torque = torque_command_t()
        self._debug = osc_debug_t()
        self._status = "starting"

    def setup(self, ctx: Context) -> None:
        """Build the controller (model copy, QP solvers) before the first state arrives."""
        self.controller = OscController(self.params, CassieModel())
        m = self.controller.model
        after = self.params.safety.plan_fallback_s
        self.fallback = PlanFallback(m, after) if after > 0.0 else None
        self._nq, self._nv = m.nq, m.nv
        self._torque.num_motors = m.nu

    def warm_up(self) -> None:
        """Run a throwaway controller through standing and walking on the IK standing pose
        (no physics: the state stays put; plans from the ALIP stand-in planner, encoded and
        decoded as the bus delivers them), so every
        kernel of both paths is compiled, or loaded from numba's cache, before the process is
        ready. Measured on a fresh clone without it: the first walking tick took 0.45 s, the
        bridge's watchdog tripped and Cassie fell as the holder let go. ~0.3 s when cached."""
        from .model import standing_pose
        from .standin_planner import StandInPlanner

        model = CassieModel()
        ctrl = OscController(self.params, model)
        q = standing_pose(model.m)
        v = np.zeros(model.m.nv)
        planner = StandInPlanner(CassieModel(model.m), vdes=(0.3, 0.0))
        walk = command_t()
        walk.mode = 0
        walk = command_t.decode(walk.encode())
        plan = None
        for k in range(WARM_UP_TICKS):  # 0.25 s standing, then walking through every phase
            t = k * 0.0005
            if t >= 0.25 and k % 10 == 0:
                # as it comes off the bus (tuples, not lists): the kernels the live plans need
                plan = mpfc_output_t.decode(planner.plan(t, q, v).encode())
            ctrl.update(t, q, v, plan, walk)

    def tick(self, ctx: Context, inbox: Inbox) -> None:
        """One robot state in, one torque command and one debug message out."""
        state: Any = inbox.trigger() or inbox.latest("state")
        if state is None:
            return
        ctrl = self.controller
        assert ctrl is not None
        q = np.asarray(state.q, dtype=float)
        v = np.asarray(state.v, dtype=float)
        if q.shape != (self._nq,) or v.shape != (self._nv,):
            # a malformed state is treated like a NaN state: safe mode, finite torques
            q = np.full(self._nq, np.nan)
            v = np.zeros(self._nv)
        t = float(state.header.utime) * 1e-6
        command = inbox.latest("command") or self._default_command
        plan = inbox.latest("plan")
        if self._first_state:
            self._first_state = False
            if not int(state.target_status) & STATUS_HOLDER_ENGAGED and (
                    self._hold_until_plan or self._stand_first_us):
                # the robot is free already: this OSC was restarted mid-run, it is not the
                # start on the gantry. No zero torque, no standing first: walk on at once
                self._hold_until_plan = False
                self._walk_from_us = 0
                ctrl.resume()
        if self._hold_until_plan:
            if plan is None or int(plan.gait_state) == GAIT_STANDING:
                # no plan yet, or the MPFC's "standing" while it has none (no footholds yet:
                # S3 starts after it). Measured live with all six processes: released on
                # that, Cassie walked 1.2 m backwards and fell before S3's first footholds
                self._publish_off(ctx, state, plan is not None)
                return
            self._hold_until_plan = False  # once: a later gap in plans is the controller's
        utime = int(state.header.utime)
        if self._walk_from_us is None:  # the first controlled tick: stand for a while
            self._walk_from_us = utime + self._stand_first_us
        if utime < self._walk_from_us:
            command = self._stand
        fb = self.fallback
        if fb is not None:  # the MPFC's plans lost while walking: own steps in place
            plan = fb.step(t, q, v, plan, ctrl.mode)
        u, dbg = ctrl.update(t, q, v, plan, command)
        if self._on_from_us is None:
            self._on_from_us = utime
        if (self._soft_start_us and utime - self._on_from_us < self._soft_start_us
                and int(state.target_status) & STATUS_HOLDER_ENGAGED):
            # the gantry start: standing's torques switched on at once against the pinned
            # pelvis bounced both feet 6 cm off the ground within 70 ms and slid them 10-20
            # cm forward; let go like that, Cassie fell backwards (live, 2026-12-07)
            u = u * (max(utime - self._on_from_us, 0) / self._soft_start_us)
        torque = u.tolist()
        if not math.isfinite(sum(torque)):  # defence in depth: never publish a NaN torque
            torque = [0.0] * len(torque)
        cmd = self._torque
        cmd.header.utime = state.header.utime
        cmd.state_packet_seq = state.packet_seq
        cmd.torque = torque
        cmd.mode = dbg.mode
        status = dbg.status
        if fb is not None and fb.active:
            status += " (MPFC plans lost: own steps in place until it is back)"
        cmd.status = self._status = status
        ctx.publish("torque", cmd)
        if not ctx.due("debug"):  # OSC_DEBUG is decimated (processes.osc.output_rate_hz)
            return
        d = self._debug
        d.header.utime = state.header.utime
        d.tick_ms = dbg.tick_ms
        d.solve_ms = dbg.solve_ms
        d.qp_status = dbg.qp_status
        d.qp_iterations = dbg.qp_iterations
        d.mode = dbg.mode
        d.status = dbg.status
        d.num_tasks = len(dbg.task_names)
        d.task_names = dbg.task_names  # the controller makes new lists every tick: no copy
        d.task_errors = dbg.task_errors
        ctx.publish("debug", d)

    def _publish_off(self, ctx: Context, state: Any, planless: bool = False) -> None:
        """Zero torque, mode 3 (off): waiting for the MPFC's first plan (``planless``: it
        runs, but has no footsteps to plan yet)."""
        cmd = self._torque
        cmd.header.utime = state.header.utime
        cmd.state_packet_seq = state.packet_seq
        cmd.torque = [0.0] * int(cmd.num_motors)
        cmd.mode = OFF
        cmd.status = self._status = (
            "off: the MPFC has no footstep plan yet (no footholds?); held" if planless
            else "off: waiting for the MPFC's first plan (held)")
        ctx.publish("torque", cmd)

    def status(self) -> str:
        """The controller's last status line (mode and, in safe mode, the reason)."""
        return self._status

    def health(self) -> int:
        """A fault after a fall (safe mode for good); a warning in safe mode that clears by
        itself (a bad input or tick: ``safety.recover_s``)."""
        if not self.in_safe_mode:
            return HEALTH_OK
        assert self.controller is not None
        return HEALTH_FAULT if self.controller.safety.terminal else HEALTH_WARNING

    def counters(self) -> dict[str, float]:
        """The controller's mode (0 walking, 1 standing, 2 safe, 3 off: waiting for a plan),
        the plan fallback's hand-overs, safe-mode episodes and recoveries."""
        c = self.controller
        if c is None:
            return {"mode": -1.0}
        fb = self.fallback
        return {"mode": float(OFF if self._hold_until_plan else c.mode),
                "plan_fallbacks": float(fb.engaged if fb is not None else 0),
                "plan_handbacks": float(fb.handed_back if fb is not None else 0),
                "safe_entries": float(c.safety.entries),
                "safe_recoveries": float(c.safety.recoveries)}

    @property
    def in_safe_mode(self) -> bool:
        """True while a fault holds the controller in joint damping."""
        return self.controller is not None and self.controller.mode == SAFE


@dataclass(frozen=True)
class Params:
    """The OSC's ``params:`` (processes.yaml, a profile's ``overrides:``)."""

    #: before the radio's first command: walk (MPFC's default velocity) or stand
    start: str = spec("walk", choices=START_MODES)
    #: zero torque (mode 3, off: the holder keeps the robot) until the MPFC's first plan
    hold_until_plan: bool = False
    #: then stand this long (sim time) before it may walk
    stand_first_s: float = spec(0.0, lo=0.0, hi=60.0, unit="s")
    #: in the holder, ramp the torques in over this long from the first controlled tick
    soft_start_s: float = spec(0.0, lo=0.0, hi=5.0, unit="s")


#: the gains file (``gains:``, hw_config/gains/osc.yaml), section by section
Gains = OscGains


def make_node(proc: ProcessConfig, profile: Profile, params: Params, gains: OscGains) -> Node:
    """The OSC of ``gains`` and ``params`` (``runtime.builder.build_node`` reads and checks
    both)."""
    return OscNode(OscParams.from_gains(gains), params.start, params.hold_until_plan,
                   params.stand_first_s, params.soft_start_s)
