"""``OscController``: the whole OSC tick (mode logic, tasks, QP (14), safety), no LCM inside.

Modes (as in ``torque_command_t.mode``): 0 walking, 1 standing, 2 safe. The controller starts
standing; it hands over to walking when the command asks to walk and a fresh MPFC plan is in
double stance (the robot is on both feet); it goes back to standing when the command or the
plan asks to stand and both feet are down. A NaN state, a fall or a missing plan while
walking puts it in safe mode (joint damping); a fall latches it, any other fault clears
after ``safety.recover_s`` of good ticks and the robot walks (or stands) on. Every published
torque is finite and within the joint limits.
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from lcmtypes import mpfc_output_t
from runtime.params import load

from .model import CassieModel
from .qp import OscQP
from .safety import SafetyMonitor
from .standing import StandingController
from .tasks import DEFAULT_GAINS_FILE, OscGains, OscParams, TaskLog
from .walking import DOUBLE_AFTER_LEFT, DOUBLE_AFTER_RIGHT, GaitPhase, WalkingController
from .walking import STANDING as GAIT_STANDING

log = logging.getLogger(__name__)
#: the narrowest stance the hand-over to standing takes (its pose: feet 27 cm apart). 10 cm
#: before: a stop on one stone eroded by S3 ended with the feet 7-8 cm apart, the gait stepped
#: in place for 2 s and fell (d_min 40 cm, seed 2002, perception); at 7 cm it stands there
#: for the trial's last 10 s, and none of 20 other trials with a stop changed (5 cm on a
#: stair tread held 2 s and tipped over sideways: measured)
STAND_MIN_WIDTH_M = 0.07
#: walking out of standing takes the leading foot's floor (``WalkingController.from_standing``)
#: once the standing controller has held the robot this long: the legs' leaf springs are
#: loaded then (after 50 ms of standing the unloaded foot lifted; the harness starts at the
#: unloaded IK pose and hands over at its second tick, 0.5 ms, where it never did: measured)
STOOD_LOADED_S = 0.02
#: the least share of the weight the CoM and its capture point must leave every contact point
#: for the hand-over to standing: the standing QP asks 15 N (``qp.standing_fz_min``) of each,
#: 4.6 % of Cassie's 33 kg (side by side, 27 cm apart, it allows the CoM 6.5 cm fore or aft of
#: the feet's centre; the 2 cm margin on the box before allowed 6 cm)
STAND_MIN_SHARE = 0.05

WALKING, STANDING, SAFE = 0, 1, 2
MODE_NAMES = {WALKING: "walking", STANDING: "standing", SAFE: "safe"}
#: consecutive failed QP solves (previous torques reused) before safe mode
MAX_QP_FAILURES = 20


@dataclass
class OscDebug:
    """What one tick did: the fields of ``osc_debug_t`` (one object, rewritten every tick)."""

    mode: int = STANDING
    status: str = ""
    tick_ms: float = 0.0
    solve_ms: float = 0.0
    qp_status: int = 0
    qp_iterations: int = 0
    task_names: list[str] = field(default_factory=list)
    task_errors: list[float] = field(default_factory=list)


def support_share(points: Any, *at: tuple[float, float]) -> float:
    """The largest share of the weight every one of ``points`` (x, y, ...) can carry with the
    centre of pressure at ``p``, the least over the points ``at`` (one hull for all of them):
    the largest w with p = sum(l_i p_i), sum(l_i) = 1, l_i >= w.
    That set is the points' hull shrunk towards their centroid c by 1 - n w, so w is the
    least, over the hull's edges, of p's distance to the edge over c's, divided by n
    (negative: p outside the hull; 1 / n at the centroid). Ours, for the hand-over to
    standing: a CoM inside the hull's box but over one foot's toe left the other foot
    unloaded under the standing QP, and it slid off its stone (measured)."""
    pts = [(float(q[0]), float(q[1])) for q in points]
    n = len(pts)
    cx = sum(q[0] for q in pts) / n
    cy = sum(q[1] for q in pts) / n
    # hull, counter-clockwise (monotone chain; a handful of points, plain Python)
    srt = sorted(set(pts))
    if len(srt) < 3:
        return -1.0

    def cross(o: tuple[float, float], a: tuple[float, float], b: tuple[float, float]) -> float:
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    lower: list[tuple[float, float]] = []
    upper: list[tuple[float, float]] = []
    for q in srt:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], q) <= 0.0:
            lower.pop()
        lower.append(q)
    for q in reversed(srt):
        while len(upper) >= 2 and cross(upper[-2], upper[-1], q) <= 0.0:
            upper.pop()
        upper.append(q)
    hull = lower[:-1] + upper[:-1]
    if len(hull) < 3:
        return -1.0  # the points on a line: no area to stand on
    share = math.inf
    for k in range(len(hull)):
        a, b = hull[k], hull[(k + 1) % len(hull)]
        # inward distances (times the edge's length) of each p and of the centroid
        dc = cross(a, b, (cx, cy))
        if dc <= 0.0:
            return -1.0
        for p in at:
            share = min(share, cross(a, b, (p[0], p[1])) / (n * dc))
    return share


def _plan_ok(plan: Any) -> bool:
    """A plan the OSC can act on: known gait state and stance, finite numbers."""
    try:
        vals = [*plan.stance_foot_world, *plan.next_footstep_world, plan.stance_yaw,
                plan.prev_switch_time_s, plan.next_switch_time_s, plan.ankle_torque]
        return (0 <= int(plan.gait_state) <= 4 and int(plan.stance) in (0, 1)
                and len(vals) == 10 and all(map(math.isfinite, map(float, vals))))
    except (AttributeError, TypeError, ValueError):
        return False


def _plan_time(plan: Any) -> float | None:
    """Sim time (s) of the state a plan was computed from (its header.utime)."""
    if plan is None:
        return None
    hdr = getattr(plan, "header", None)
    return None if hdr is None else float(hdr.utime) * 1e-6


class OscController:
    """The OSC of Section III-E / V: call ``update`` once per robot state."""

    def __init__(self, params: OscParams | None = None, model: CassieModel | None = None,
                 gains_file: str | Path | None = None) -> None:
        t_setup = time.perf_counter()
        if params is None:  # the gains file (default hw_config/gains/osc.yaml)
            path = gains_file if gains_file is not None else DEFAULT_GAINS_FILE
            params = OscParams.from_gains(load(OscGains, path))
        self.params = params
        self.model = model if model is not None else CassieModel()
        m = self.model
        self.qp = OscQP(m, self.params.qp)
        self.rows = self.qp.rows
        self.log = TaskLog()
        self.standing = StandingController(self.params.standing, m.nv)
        self.walking = WalkingController(self.params.walking, m.nv)
        self.safety = SafetyMonitor(self.params.safety, m.motor_dof, m.u_max)
        self.mode = STANDING
        self.u = np.zeros(m.nu)
        self.qp_failures = 0
        self.debug = OscDebug()
        self.stance = np.ones(4, dtype=bool)
        self.waiting = False  # walking asked, plan not yet in double stance
        self._mode_before_safe = STANDING  # the mode a fault interrupted
        self._safe_since = 0.0  # sim time safe mode began
        self._resume = False  # ``resume``: walk on the first fresh plan, any phase
        self._rigid_swing_springs = self.params.springs == "rigid_swing"
        self._q = np.zeros(m.nq)
        self._v = np.zeros(m.nv)
        #: per leg, the qpos and dof indices of its two leaf springs
        self._spring_idx = [(*(int(i) for i in m.spring_qpos[2 * s : 2 * s + 2]),
                             *(int(i) for i in m.spring_dof[2 * s : 2 * s + 2])) for s in (0, 1)]
        self._u_min = -m.u_max
        if (setup_s := time.perf_counter() - t_setup) > 3.0:
            log.info("OSC set up in %.1f s: numba compiled its kernels (first start on this "
                     "machine or after a code change; cached in __pycache__ from now)", setup_s)

    # ------------------------------------------------------------------ public
    def reset(self) -> None:
        """Clear any fault, a fall too, and restart from standing (operator action)."""
        self.safety.reset()
        self.mode = STANDING
        self.standing.started = False
        self.walking.reset()
        self.qp_failures = 0

    def update(self, t_s: float, q: np.ndarray, v: np.ndarray, plan: Any | None = None,
               command: Any | None = None) -> tuple[np.ndarray, OscDebug]:
        """One tick: joint-side torques (10, actuator order, N m) and debug info.

        ``plan`` is an ``mpfc_output_t`` (or any object with its fields), ``command`` a
        ``command_t`` (mode 0 walk, 1 stand; yaw_rate). None means not received yet.
        """
        t0 = time.perf_counter()
        dbg = self.debug
        self.log.reset()
        self.safety.now = t_s
        fault = self.safety.check_state(q, v)
        plan_ok = plan is not None and _plan_ok(plan)
        if fault is not None and not self._recover(t_s, plan, command, plan_ok):
            return self._safe(q, v, fault, t0)
        m = self.model
        phase = GaitPhase.from_plan(plan, t_s) if plan_ok else None
        swing = self._swing_leg(phase)
        if swing is not None:
            # The OSC's model holds the leaf springs rigid (14c). Fed the swing leg's measured
            # deflection, the swing-foot feedback chases the springs' ringing through motors
            # that cannot damp it (non-collocated) and the foot lands centimetres off target;
            # the stance leg keeps its measured deflection (it sets the CoM height and the
            # contact-point geometry the ALIP state is measured from).
            self._q[:] = q
            self._v[:] = v
            q0, q1, d0, d1 = self._spring_idx[swing]
            self._q[q0] = self._q[q1] = 0.0
            self._v[d0] = self._v[d1] = 0.0
            q, v = self._q, self._v
        try:
            m.update(q, v)
            pc = m.p_contact_l
            fault = self.safety.check_fall(float(q[2]) - min(pc[0][2], pc[1][2], pc[2][2],
                                                                pc[3][2]))
            if fault is not None:
                return self._safe(q, v, fault, t0)
            if self._resume and self.mode == STANDING and self._can_walk_now(
                    t_s, plan, command, plan_ok):
                self._resume = False
                self.mode = WALKING
                self.walking.reset()
            fault = self._choose_mode(t_s, plan, command, plan_ok)
            if fault is not None:
                return self._safe(q, v, fault, t0)
            if self.mode == STANDING and not self.standing.started:
                self.standing.start(t_s, m, q)
            self.rows.reset()
            if self.mode == WALKING:
                yaw_rate = float(command.yaw_rate) if command is not None else 0.0
                if not math.isfinite(yaw_rate):
                    yaw_rate = 0.0  # a garbled radio command must not reach the QP
                if phase is None:  # cannot happen: _choose_mode leaves walking without one
                    raise ValueError("walking without a valid MPFC plan")
                stance = self.walking.add_tasks(self.rows, self.log, self.qp, m, q, v, t_s,
                                                plan, phase, yaw_rate)
            else:
                self.qp.moment_count = 0
                stance = self.standing.add_tasks(self.rows, self.log, m, q, v, t_s)
            self.stance = stance
            fz_min = self.params.qp.standing_fz_min if self.mode == STANDING else 0.0
            walking = self.mode == WALKING
            res = self.qp.solve(self.rows, stance, fz_min,
                                self.walking.fz_max if walking else None,
                                self.walking.fz_floor if walking else None)
        except (ArithmeticError, ValueError, np.linalg.LinAlgError) as e:
            # a degenerate state (singular matrices, a malformed plan): damp, never crash
            self.safety.latch(f"controller error: {type(e).__name__}: {e}")
            return self._safe(q, v, self.safety.fault or "controller error", t0)
        if res.status == 1:
            self.qp_failures = 0
            np.minimum(np.maximum(res.u, self._u_min, out=self.u), m.u_max, out=self.u)
            status = MODE_NAMES[self.mode]
            if self.waiting:
                status += " (walk asked: waiting for a double-stance plan to hand over)"
            elif self.mode == WALKING and command is not None and int(command.mode) != 0:
                status += " (stand asked: waiting for double stance with the CoM at rest)"
        else:
            self.qp_failures += 1
            status = f"{MODE_NAMES[self.mode]}: QP status {res.status}, previous torques"
            if self.qp_failures >= MAX_QP_FAILURES:
                self.safety.latch(f"QP failed {self.qp_failures} ticks in a row")
                return self._safe(q, v, self.safety.fault or "QP failure", t0)
        if not math.isfinite(float(self.u.sum())):
            self.safety.latch("non-finite torque from the QP")
            return self._safe(q, v, self.safety.fault or "non-finite torque", t0)
        dbg.mode = self.mode
        dbg.status = status
        dbg.qp_status = res.status
        dbg.qp_iterations = res.iterations
        dbg.solve_ms = res.solve_s * 1e3
        dbg.task_names = list(self.log.names)
        dbg.task_errors = list(self.log.errors)
        dbg.tick_ms = (time.perf_counter() - t0) * 1e3
        return self.u.copy(), dbg

    # ------------------------------------------------------------------ internals
    def _swing_leg(self, phase: GaitPhase | None) -> int | None:
        """The leg swinging this tick whose springs the OSC treats as rigid, or None."""
        if not self._rigid_swing_springs or self.mode != WALKING or phase is None:
            return None  # (phase: None unless the plan passed _plan_ok this tick)
        return 1 - phase.stance if phase.single_stance else None

    def _choose_mode(self, t: float, plan: Any | None, command: Any | None,
                     plan_ok: bool) -> str | None:
        """Standing <-> walking hand-over; a fault string when walking lost its plan."""
        want_walk = command is not None and int(command.mode) == 0
        if plan is not None and not plan_ok:
            if self.mode == WALKING:
                self.safety.latch("invalid MPFC plan (non-finite or unknown gait state)")
                return self.safety.fault
            plan = None  # standing: never hand over to a bad plan
        plan_t = _plan_time(plan)
        fresh = plan is not None and (plan_t is None or
                                      t - plan_t <= self.params.safety.plan_timeout_s)
        plan_walks = plan is not None and int(plan.gait_state) != GAIT_STANDING
        if self.mode == STANDING:
            solved = int(getattr(plan, "solve_status", 0)) != mpfc_output_t.SOLVE_ERROR
            ok = want_walk and fresh and plan_walks and solved
            # hand over only in double stance: the robot stands on both feet, so does the plan
            if ok and int(plan.gait_state) in (DOUBLE_AFTER_LEFT, DOUBLE_AFTER_RIGHT):
                self.mode = WALKING
                self.walking.reset(from_standing=self.standing.started
                                   and t - self.standing.t0 >= STOOD_LOADED_S)
            self.waiting = ok and self.mode == STANDING
        elif self.mode == WALKING:
            # a plan without a header (a bare object, in tests) counts as fresh
            fault = self.safety.check_plan(t, None if plan is None else
                                           (t if plan_t is None else plan_t))
            if fault is not None:
                return fault
            stand_now = (not want_walk) or not plan_walks
            # back to standing only in double stance with both feet really down (standing puts
            # force on all four points; a foot still in the air would throw the robot) and the
            # CoM nearly at rest over the feet (blade feet cannot stop a moving CoM: the plan
            # has to bring it to rest first, by stepping)
            if (stand_now and int(plan.gait_state) not in (0, 1)
                    and t >= float(plan.prev_switch_time_s) + 0.03 and self._feet_down()
                    and self._feet_apart() and self._com_settled()):
                self.mode = STANDING
                self.standing.started = False
        return None

    def _recover(self, t: float, plan: Any | None, command: Any | None, plan_ok: bool) -> bool:
        """Leave safe mode once its fault clears (``SafetyMonitor.try_recover``): back to
        walking when it walked before and a fresh walking plan and a walk command are there
        (mid-swing too: the swing restarts from where the foot is), else standing. A fall
        found on this tick puts it straight back."""
        if not self.safety.try_recover():
            return False
        self.qp_failures = 0
        self.walking.reset()
        self.standing.started = False
        resume = self._mode_before_safe == WALKING and self._can_walk_now(t, plan, command,
                                                                         plan_ok)
        self.mode = WALKING if resume else STANDING
        log.warning("OSC left safe mode after %.0f ms: %s", 1e3 * (t - self._safe_since),
                    MODE_NAMES[self.mode])
        return True

    def _can_walk_now(self, t: float, plan: Any | None, command: Any | None,
                      plan_ok: bool) -> bool:
        """A fresh, valid walking plan and a walk command: walking may take over in any phase
        of the gait (a recovery, a restart mid-walk), not only in double stance."""
        plan_t = _plan_time(plan)
        return (plan_ok and command is not None and int(command.mode) == 0
                and int(plan.gait_state) != GAIT_STANDING
                and (plan_t is None or t - plan_t <= self.params.safety.plan_timeout_s))

    def resume(self) -> None:
        """This controller takes over a robot that is already walking (the OSC restarted
        mid-walk): it walks on the first fresh walking plan, in whatever phase, instead of
        standing until a double-stance hand-over (measured: a restarted OSC that stood first
        let the walking robot fall)."""
        self._resume = True

    def _feet_down(self, dz: float = 0.015, vz: float = 0.15) -> bool:
        """Both blades down (kinematic check, no contact sensing): every contact point within
        ``dz`` of the lowest one and moving slower than ``vz`` vertically."""
        p, v = self.model.p_contact_l, self.model.v_contact_l
        z0 = min(pt[2] for pt in p)
        return all(pt[2] - z0 < dz for pt in p) and all(abs(vv[2]) < vz for vv in v)

    def _feet_apart(self, width: float = STAND_MIN_WIDTH_M) -> bool:
        """The feet stand at least ``width`` apart across the blades (the standing controller
        balances on the box of both feet: ``STAND_MIN_WIDTH_M``); narrower, the gait steps
        on."""
        p = self.model.p_contact_l
        fx, fy = p[0][0] - p[1][0], p[0][1] - p[1][1]  # the left blade, rear to front
        n = math.hypot(fx, fy)
        if n < 1e-6:
            return True
        dx = 0.5 * (p[0][0] + p[1][0] - p[2][0] - p[3][0])
        dy = 0.5 * (p[0][1] + p[1][1] - p[2][1] - p[3][1])
        return abs(fx * dy - fy * dx) / n >= width

    def _com_settled(self, speed: float = 0.1) -> bool:
        """The CoM can be stopped without a step: it moves slower than ``speed`` (m/s,
        horizontal), and the CoM and its instantaneous capture point com + v / omega (omega =
        sqrt(g / z), LIP) both leave each of the four contact points at least
        ``STAND_MIN_SHARE`` of the weight (``support_share``). (The capture point alone let
        the hand-back happen at a touchdown at full walking speed, where the long double-stance
        box holds it: the standing CoM task then braked the robot, the rear foot unloaded and
        slid, and Cassie fell within 1.1 s; so a stand is asked for by stepping to a stop
        first. The hull's box with a 2 cm margin let it happen after a stop's step back put
        the front foot under the CoM, the feet 14 cm apart fore-aft and 10 cm across: the CoM
        was over the front blade's toe, standing unloaded the rear foot and it slid off its
        stone, measured on stones with perception, d_min 40 cm, seed 2016.)"""
        m = self.model
        vx, vy = m.com_vel_l[0], m.com_vel_l[1]
        if vx * vx + vy * vy > speed * speed:
            return False
        pts = m.p_contact_l
        z = m.com_l[2] - 0.25 * sum(p[2] for p in pts)
        inv_omega = math.sqrt(max(z, 0.3) / 9.81)
        com = (m.com_l[0], m.com_l[1])
        cp = (com[0] + vx * inv_omega, com[1] + vy * inv_omega)
        return support_share(pts, com, cp) >= STAND_MIN_SHARE

    def _safe(self, q: np.ndarray, v: np.ndarray, reason: str, t0: float) -> tuple[
            np.ndarray, OscDebug]:
        if self.mode != SAFE:
            self._mode_before_safe = self.mode
            self._safe_since = self.safety.now
        self.mode = SAFE
        self.u[:] = self.safety.damping(v)
        dbg = self.debug
        dbg.mode = SAFE
        dbg.status = f"safe mode (joint damping): {reason}"
        dbg.qp_status = 0
        dbg.qp_iterations = 0
        dbg.solve_ms = 0.0
        dbg.task_names = []
        dbg.task_errors = []
        dbg.tick_ms = (time.perf_counter() - t0) * 1e3
        return self.u.copy(), dbg
