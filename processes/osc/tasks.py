"""OSC task definitions and the gains file (Tables VI-VII): task-space PD rows for the QP (14a).

Every task turns a desired output (position, velocity, feed-forward acceleration) into rows of
``J dv + Jdot v ~= ydd_cmd`` with ``ydd_cmd = ydd_des + Kp (y_des - y) + Kd (yd_des - yd)``
(Section III-E) and appends them to a ``TaskRows`` stack with its weights ``W``. The rows are
compiled (numba): one kernel per tick writes all of a mode's tasks (``walking_rows``,
``standing_rows``); the controllers compute their references in Python.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from pathlib import Path

import numba
import numpy as np

from runtime.errors import ConfigError
from runtime.params import spec

from .qp import ROW_COM, ROW_CONTACT, ROW_DOF, QpWeights

DEFAULT_GAINS_FILE = Path(__file__).resolve().parents[2] / "hw_config" / "gains" / "osc.yaml"

SPRING_MODES = ("rigid_swing", "measured")
SWING_TOE_MODES = ("plane", "level")


# ---------------------------------------------------------------------- the gains file
# hw_config/gains/osc.yaml as runtime.params reads it (the process module's ``Gains``):
# ``OscGains``, section by section; ``OscParams.from_gains`` is what the controller runs on.
Vec3 = tuple[float, float, float]
Vec10 = tuple[float, float, float, float, float, float, float, float, float, float]


@dataclass(frozen=True)
class AxisGains3:
    """A task with 3 axes: weight W_i in (14a) and task-space PD gains, one per axis."""

    w: Vec3 = spec((0.0, 0.0, 0.0), lo=0.0)
    kp: Vec3 = spec((0.0, 0.0, 0.0), lo=0.0)
    kd: Vec3 = spec((0.0, 0.0, 0.0), lo=0.0)


@dataclass(frozen=True)
class AxisGains1:
    """A task with 1 axis (a joint, the toe angle): weight and PD gains."""

    w: float = spec(0.0, lo=0.0)
    kp: float = spec(0.0, lo=0.0)
    kd: float = spec(0.0, lo=0.0)


@dataclass(frozen=True)
class WalkingGains:
    """``walking:``: the tasks of Table VII and the output synthesis of Section V."""

    pelvis: AxisGains3  # roll, pitch, yaw rate
    com: AxisGains3
    swing_foot: AxisGains3
    toe: AxisGains1
    hip_yaw: AxisGains1
    ankle_torque_weight: float = spec(10.0, lo=0.0)
    com_height: float = spec(0.85, lo=0.5, hi=1.1, unit="m")  # H of (22), Table V
    com_filter_hz: float = spec(100.0, lo=1.0, hi=1000.0, unit="Hz")  # Section V-A
    com_clip: float = spec(0.025, lo=0.0, hi=0.2, unit="m")  # |z_des - z_com|, Section V-A
    swing_clearance: float = spec(0.15, lo=0.0, hi=0.4, unit="m")  # c of Section V-B-1
    swing_degree: int = spec(8, lo=7, hi=12)  # polynomial degree of the swing QP (23)
    swing_step_up_min: float = spec(0.0, lo=0.0, hi=1.0, unit="m")
    swing_step_up_clearance: float = spec(0.06, lo=0.0, hi=0.4, unit="m")
    swing_step_up_height: float = spec(0.04, lo=0.0, hi=0.2, unit="m")
    swing_lift_tau: float = spec(0.25, lo=0.1, hi=0.45)  # fraction of T
    swing_approach_tau: float = spec(0.8, lo=0.55, hi=0.9)  # fraction of T
    swing_toe: str = spec("plane", choices=SWING_TOE_MODES)
    start_fz_min: float = spec(15.0, lo=0.0, hi=500.0, unit="N")  # WalkingParams
    start_unload_s: float = spec(0.15, lo=0.0, hi=2.0, unit="s")  # WalkingParams


@dataclass(frozen=True)
class StandingGains:
    """``standing:``: CoM over the centre of the feet, pelvis level, hip yaw straight."""

    com: AxisGains3
    pelvis: AxisGains3
    hip_yaw: AxisGains1
    com_height: float = spec(0.80, lo=0.5, hi=1.1, unit="m")
    com_offset_x: float = spec(0.0, lo=-0.1, hi=0.1, unit="m")
    height_rate: float = spec(0.1, lo=0.0, hi=1.0, unit="m/s")
    xy_ramp_s: float = spec(1.0, lo=0.0, hi=10.0, unit="s")


@dataclass(frozen=True)
class SafetyGains:
    """``safety:``: fault thresholds and the safe-mode joint damping."""

    fall_height: float = spec(0.6, lo=0.0, hi=1.0, unit="m")
    plan_timeout_s: float = spec(0.2, lo=0.001, hi=5.0, unit="s")
    plan_fallback_s: float = spec(0.1, lo=0.0, hi=5.0, unit="s")  # at most plan_timeout_s
    recover_s: float = spec(0.01, lo=0.0005, hi=10.0, unit="s")
    damping: Vec10 = spec((10.0, 10.0, 10.0, 10.0, 2.0) * 2, lo=0.0, unit="N m s/rad")

    def __post_init__(self) -> None:
        if self.plan_fallback_s > self.plan_timeout_s:
            raise ConfigError("<SafetyGains>", "plan_fallback_s",
                              f"{self.plan_fallback_s} is above plan_timeout_s "
                              f"({self.plan_timeout_s})", f"[0.0, {self.plan_timeout_s}] s")


@dataclass(frozen=True)
class OscGains:
    """``hw_config/gains/osc.yaml``: QP weights, walking and standing tasks, safety."""

    qp: QpWeights
    walking: WalkingGains
    standing: StandingGains
    safety: SafetyGains = spec(default_factory=SafetyGains)
    springs: str = spec("rigid_swing", choices=SPRING_MODES)


# ---------------------------------------------------------------------- what the OSC runs on
@dataclass
class TaskGains:
    """Weight and PD gains of one task, one entry per task axis."""

    w: np.ndarray
    kp: np.ndarray
    kd: np.ndarray

    def __post_init__(self) -> None:
        self.refresh()

    @classmethod
    def of(cls, g: AxisGains3 | AxisGains1) -> TaskGains:
        """The arrays of a task's gains in the file."""
        return cls(*(np.array(v if isinstance(v, tuple) else (v,), dtype=float)
                     for v in (g.w, g.kp, g.kd)))

    def refresh(self) -> None:
        """Update the copies used on the hot path (call after editing the arrays)."""
        self.w_list = [float(x) for x in self.w]
        self.kp_list = [float(x) for x in self.kp]
        self.kd_list = [float(x) for x in self.kd]
        self.active = [a for a, x in enumerate(self.w_list) if x > 0.0]
        #: [w; kp; kd] (3, axes) as the compiled task rows read them
        self.packed = np.array([self.w, self.kp, self.kd], dtype=float)


@dataclass
class WalkingParams:
    """Walking tasks (Table VII) and the output-synthesis constants of Section V."""

    pelvis: TaskGains
    com: TaskGains
    swing_foot: TaskGains
    toe: TaskGains
    hip_yaw: TaskGains
    ankle_torque_weight: float = 10.0
    com_height: float = 0.85  # H of (22), Table V
    com_filter_hz: float = 100.0  # low-pass on (k_x, k_y), Section V-A
    com_clip: float = 0.025  # |z_des - z_com| limit, Section V-A
    swing_clearance: float = 0.15  # c of Section V-B-1
    swing_degree: int = 8  # polynomial degree of the swing QP (23)
    #: rise (m) from which a swing uses the step-up waypoints (walking.swing_waypoints); 0: the
    #: paper's midpoint for every swing
    swing_step_up_min: float = 0.0
    swing_step_up_clearance: float = 0.06  # step up: midpoint height over the higher end
    swing_step_up_height: float = 0.04  # step up: lift/approach points' height over it
    swing_lift_tau: float = 0.25  # step up: the lift point's time, fraction of T
    swing_approach_tau: float = 0.8  # step up: the approach point's time, fraction of T
    #: swing toe target: "plane" = foot at atan(k_x) (Section V-C), "level" = foot level
    swing_toe: str = "plane"
    #: walking out of standing (ours): the first double stance's leading foot carries at
    #: least its standing share (m g / 4 a point) falling to this over ``start_unload_s``
    #: (``WalkingController._double_stance``)
    start_fz_min: float = 15.0
    start_unload_s: float = 0.15


@dataclass
class StandingParams:
    """Standing: CoM over the centre of the feet, pelvis level, hip yaw straight."""

    com: TaskGains
    pelvis: TaskGains
    hip_yaw: TaskGains
    com_height: float = 0.80
    com_offset_x: float = 0.0  # CoM target ahead of the feet's centre (m)
    height_rate: float = 0.1  # m/s ramp of the CoM height target from its start value
    xy_ramp_s: float = 1.0  # s to move the CoM x, y target from its start to the feet's centre


@dataclass
class SafetyParams:
    """Fault thresholds and the safe-mode joint damping (joint-side N m s/rad)."""

    fall_height: float = 0.6
    plan_timeout_s: float = 0.2
    #: walking with no plan newer than this: the OSC's own steps in place
    #: (``fallback.PlanFallback``); 0 turns it off (then plan_timeout_s latches safe mode)
    plan_fallback_s: float = 0.1
    #: a fault other than a fall clears after this long (s, sim time) of good ticks
    recover_s: float = 0.01
    damping: np.ndarray = field(
        default_factory=lambda: np.array([10.0, 10.0, 10.0, 10.0, 2.0] * 2)
    )


def _runtime(cls: type, g: object) -> object:
    """``cls`` with the values of the section ``g`` of the same field names: a task's gains
    as ``TaskGains``, a vector as an array."""
    kw = {}
    for f in fields(cls):
        v = getattr(g, f.name)
        if isinstance(v, (AxisGains3, AxisGains1)):
            v = TaskGains.of(v)
        elif isinstance(v, tuple):
            v = np.array(v, dtype=float)
        kw[f.name] = v
    return cls(**kw)


@dataclass
class OscParams:
    """Everything the OSC runs on: ``hw_config/gains/osc.yaml`` (``from_gains``), its task
    gains as arrays, editable (call ``TaskGains.refresh`` after editing one)."""

    qp: QpWeights
    walking: WalkingParams
    standing: StandingParams
    safety: SafetyParams
    #: "rigid_swing": the OSC sees the swing leg's leaf springs at zero deflection (its model
    #: holds them rigid, (14c)); "measured": every estimated deflection enters the kinematics
    springs: str = "rigid_swing"

    @classmethod
    def from_gains(cls, gains: OscGains) -> OscParams:
        """The controller's copy of a gains file's values (``runtime.params.load(OscGains,
        path)``)."""
        return cls(qp=gains.qp, walking=_runtime(WalkingParams, gains.walking),
                   standing=_runtime(StandingParams, gains.standing),
                   safety=_runtime(SafetyParams, gains.safety), springs=gains.springs)


# ---------------------------------------------------------------------- tasks
class TaskLog:
    """Names and tracking-error norms of the tasks of one tick (for ``osc_debug_t``)."""

    def __init__(self) -> None:
        self.names: list[str] = []
        self.errors: list[float] = []

    def reset(self) -> None:
        """Start a new tick."""
        self.names.clear()
        self.errors.clear()

    def add(self, name: str, *err: float) -> None:
        """Record a task and the norm of its error components."""
        self.names.append(name)
        self.errors.append(math.sqrt(sum(e * e for e in err)))


# Compiled task rows (numba, cached on disk). Each writes its rows ``J dv ~= b`` into a
# TaskRows stack's arrays (``ri``: source rows i0, i1; ``rf``: c0, c1, b, w; a row's J is
# c0 (S[i0] + c1 S[i1]), see ``qp.ROW_*``) from row ``n`` on, with b = ydd_cmd - Jdot v and
# ydd_cmd = ydd_des + Kp (y_des - y) + Kd (yd_des - yd) (Section III-E), stores the norm of its
# error in ``errs[k]`` and returns the next free row. ``kin`` is ``CassieModel.kin`` (rows:
# R_pelvis 0-2, CoM 5, CoM velocity 6, CoM bias acceleration 7, contact points 8-11, their
# velocities 12-15; world frame); ``g`` a task's packed gains [w; kp; kd]
# (``TaskGains.packed``).
# The walking and standing controllers call them from one kernel per tick each.
_jit = numba.njit(cache=True, nogil=True)
KIN_R, KIN_COM, KIN_COM_VEL, KIN_COM_DOT_V, KIN_P_CONTACT, KIN_V_CONTACT = 0, 5, 6, 7, 8, 12


@_jit
def put_row(ri: np.ndarray, rf: np.ndarray, n: int, i0: int, c0: float, i1: int, c1: float,
            b: float, w: float) -> int:
    """Row n = c0 (S[i0] + c1 S[i1]) with right-hand side b and weight w; returns n + 1."""
    if n >= ri.shape[0] or n >= rf.shape[0]:  # compiled code has no bounds checks
        raise IndexError("task row stack full")
    ri[n, 0] = i0
    ri[n, 1] = i1
    rf[n, 0] = c0
    rf[n, 1] = c1
    rf[n, 2] = b
    rf[n, 3] = w
    return n + 1


@_jit
def com_rows(kin: np.ndarray, g: np.ndarray, pos: np.ndarray, vel: np.ndarray,
             acc: np.ndarray, ri: np.ndarray, rf: np.ndarray, n: int, errs: np.ndarray,
             k: int) -> int:
    """CoM position rows (world frame, J = J_com), skipping axes with zero weight."""
    s = 0.0
    for a in range(3):
        if g[0, a] > 0.0:
            e = pos[a] - kin[KIN_COM, a]
            s += e * e
            ydd = acc[a] + g[1, a] * e + g[2, a] * (vel[a] - kin[KIN_COM_VEL, a])
            n = put_row(ri, rf, n, ROW_COM + a, 1.0, -1, 0.0, ydd - kin[KIN_COM_DOT_V, a],
                        g[0, a])
    errs[k] = math.sqrt(s)
    return n


@_jit
def pelvis_rows(kin: np.ndarray, v: np.ndarray, g: np.ndarray, yaw_des: float,
                yaw_rate_des: float, ri: np.ndarray, rf: np.ndarray, n: int, errs: np.ndarray,
                k: int) -> int:
    """Pelvis roll/pitch/yaw (Tables VI-VII) on the body-frame angular acceleration dv[3:6].

    MuJoCo's free joint velocity v[3:6] is the body-frame angular velocity, so J selects it
    and Jdot v = 0. The error is the body-frame rotation vector of E = R' Rz(yaw_des); a yaw
    Kp of 0 (walking) leaves only yaw-rate tracking; the desired body rate is the world z
    rate expressed in the body frame (R' e_z)."""
    R = kin[KIN_R : KIN_R + 3]
    cy, sy = math.cos(yaw_des), math.sin(yaw_des)
    e00 = R[0, 0] * cy + R[1, 0] * sy
    e01 = -R[0, 0] * sy + R[1, 0] * cy
    e02 = R[2, 0]
    e10 = R[0, 1] * cy + R[1, 1] * sy
    e11 = -R[0, 1] * sy + R[1, 1] * cy
    e12 = R[2, 1]
    e20 = R[0, 2] * cy + R[1, 2] * sy
    e21 = -R[0, 2] * sy + R[1, 2] * cy
    e22 = R[2, 2]
    # rotation vector (axis * angle) of E
    c = max(-1.0, min(1.0, 0.5 * (e00 + e11 + e22 - 1.0)))
    ang = math.acos(c)
    f = 0.5 if ang < 1e-6 else ang / (2.0 * math.sin(ang))
    e = ((e21 - e12) * f, (e02 - e20) * f, (e10 - e01) * f)
    s = 0.0
    for a in range(3):
        ydd = g[1, a] * e[a] + g[2, a] * (R[2, a] * yaw_rate_des - v[3 + a])
        n = put_row(ri, rf, n, ROW_DOF + 3 + a, 1.0, -1, 0.0, ydd, g[0, a])
        s += e[a] * e[a]
    errs[k] = math.sqrt(s)
    return n


@_jit
def foot_position_rows(kin: np.ndarray, jc_dot_v: np.ndarray, side: int, g: np.ndarray,
                       pos: np.ndarray, vel: np.ndarray, acc: np.ndarray, ri: np.ndarray,
                       rf: np.ndarray, n: int, errs: np.ndarray, k: int) -> int:
    """Swing-foot position: the midpoint of the blade's two contact points (world frame),
    J = (Jc_front + Jc_rear) / 2."""
    f, r = kin[KIN_P_CONTACT + 2 * side], kin[KIN_P_CONTACT + 2 * side + 1]
    fv, rv = kin[KIN_V_CONTACT + 2 * side], kin[KIN_V_CONTACT + 2 * side + 1]
    j0 = 6 * side  # the front point's Jc rows; the rear point's follow
    s = 0.0
    for a in range(3):
        e = pos[a] - 0.5 * (f[a] + r[a])
        s += e * e
        b = (acc[a] + g[1, a] * e + g[2, a] * (vel[a] - 0.5 * (fv[a] + rv[a]))
             - 0.5 * (jc_dot_v[j0 + a] + jc_dot_v[j0 + a + 3]))
        n = put_row(ri, rf, n, ROW_CONTACT + j0 + a, 0.5, ROW_CONTACT + j0 + 3 + a, 1.0, b,
                    g[0, a])
    errs[k] = math.sqrt(s)
    return n


@_jit
def foot_pitch_rows(kin: np.ndarray, jc_dot_v: np.ndarray, side: int, g: np.ndarray,
                    pitch_des: float, ri: np.ndarray, rf: np.ndarray, n: int,
                    errs: np.ndarray, k: int) -> int:
    """Toe angle as the world pitch of the foot blade (Section V-C: foot at atan(k_x)).

    pitch = asin(dz / L) with dz the height of the front point over the rear one, so
    d(pitch)/dt = (Jz_front - Jz_rear) v / (L cos(pitch)).
    """
    f, r = kin[KIN_P_CONTACT + 2 * side], kin[KIN_P_CONTACT + 2 * side + 1]
    pitch = math.atan2(f[2] - r[2], math.hypot(f[0] - r[0], f[1] - r[1]))
    L = math.sqrt((f[0] - r[0]) ** 2 + (f[1] - r[1]) ** 2 + (f[2] - r[2]) ** 2)
    scale = 1.0 / (L * max(math.cos(pitch), 0.2))
    i = 6 * side
    jdv = (jc_dot_v[i + 2] - jc_dot_v[i + 5]) * scale
    rate = (kin[KIN_V_CONTACT + 2 * side, 2] - kin[KIN_V_CONTACT + 2 * side + 1, 2]) * scale
    e = pitch_des - pitch
    ydd = g[1, 0] * e - g[2, 0] * rate
    errs[k] = math.sqrt(e * e)
    # J = (Jz_front - Jz_rear) * scale
    return put_row(ri, rf, n, ROW_CONTACT + i + 2, scale, ROW_CONTACT + i + 5, -1.0,
                   ydd - jdv, g[0, 0])


@_jit
def joint_row(q: np.ndarray, v: np.ndarray, qpos: int, dof: int, g: np.ndarray,
              q_des: float, ri: np.ndarray, rf: np.ndarray, n: int, errs: np.ndarray,
              k: int) -> int:
    """One joint angle (hip yaw): a selector row, Jdot v = 0."""
    e = q_des - q[qpos]
    ydd = g[1, 0] * e - g[2, 0] * v[dof]
    errs[k] = math.sqrt(e * e)
    return put_row(ri, rf, n, ROW_DOF + dof, 1.0, -1, 0.0, ydd, g[0, 0])


@_jit
def moment_row(kin: np.ndarray, row: np.ndarray, first: int, last: int, about: np.ndarray,
               ax: float, ay: float, az: float) -> None:
    """``row`` (3 per contact point) = the moment along (ax, ay, az) about ``about`` of the
    forces at contact points first..last: axis . ((p_i - c) x f_i) = f_i . (axis x (p_i - c))."""
    for i in range(row.size):
        row[i] = 0.0
    for i in range(first, last + 1):
        p = kin[KIN_P_CONTACT + i]
        rx, ry, rz = p[0] - about[0], p[1] - about[1], p[2] - about[2]
        row[3 * i] = ay * rz - az * ry
        row[3 * i + 1] = az * rx - ax * rz
        row[3 * i + 2] = ax * ry - ay * rx


# ---------------------------------------------------------------------- one kernel per tick
# (here, beside the rows they call: numba's cache does not notice edits of a callee in
# another file, so a caller compiled elsewhere could keep running stale task code)
#: the standing tasks in row order, as the debug message names them
STANDING_TASKS = ("com", "pelvis_rpy", "left_hip_yaw", "right_hip_yaw")


@_jit
def standing_rows(kin: np.ndarray, q: np.ndarray, v: np.ndarray, ri: np.ndarray,
                  rf: np.ndarray, n: int, errs: np.ndarray, g_com: np.ndarray,
                  g_pelvis: np.ndarray, g_hip: np.ndarray, x: float, y: float, z: float,
                  yaw: float, hip_qpos: np.ndarray, hip_dof: np.ndarray,
                  hip_des: np.ndarray) -> int:
    """The standing task rows of one tick (Table VI, the rows above): CoM at (x, y, z) at
    rest, pelvis level at ``yaw``, both hip yaws held at ``hip_des``."""
    pos = np.empty(3)
    pos[0], pos[1], pos[2] = x, y, z
    zero = np.zeros(3)
    n = com_rows(kin, g_com, pos, zero, zero, ri, rf, n, errs, 0)
    n = pelvis_rows(kin, v, g_pelvis, yaw, 0.0, ri, rf, n, errs, 1)
    for side in range(2):
        n = joint_row(q, v, hip_qpos[side], hip_dof[side], g_hip, hip_des[side], ri, rf, n,
                      errs, 2 + side)
    return n


#: the walking tasks in row order, as the debug message names them
SINGLE_STANCE_TASKS = ("com", "pelvis_rpy", "swing_foot", "swing_toe", "swing_hip_yaw")
DOUBLE_STANCE_TASKS = ("com", "pelvis_rpy")


@_jit
def walking_rows(kin: np.ndarray, jc_dot_v: np.ndarray, q: np.ndarray, v: np.ndarray,
                 ri: np.ndarray, rf: np.ndarray, n: int, errs: np.ndarray,
                 moment_rows: np.ndarray, g_com: np.ndarray, g_pelvis: np.ndarray,
                 g_foot: np.ndarray, g_toe: np.ndarray, g_hip: np.ndarray, z: float,
                 zd: float, yaw_rate: float, yaw: float, single: bool, stance: int,
                 swing_ref: np.ndarray, toe: float, hip_qpos: int, hip_dof: int, ankle: bool,
                 cop_f: float) -> int:
    """The walking task rows of one tick (Tables VI-VII, the rows above).

    Always: CoM height z (zdot zd) on the footstep plane (21)-(22) (the x, y weights are 0)
    and pelvis roll/pitch to zero with the commanded yaw rate (Section V-C). Single stance
    (``single``): the swing foot on ``swing_ref`` [pos; vel; acc] of (23), its toe at ``toe``,
    its hip yaw at zero, and with ``ankle`` moment row 0 = the ground moment about the stance
    blade's midpoint along the stance frame's y axis (the MPFC ankle torque, Section V-D).
    Double stance with ``cop_f`` >= 0: moment rows 0-1 = the moments (stance x, y axes)
    about the CoP p_- + f (p_+ - p_-) of (2), p_-/p_+ the trailing/leading blade midpoints.
    """
    c = kin[KIN_COM]
    cv = kin[KIN_COM_VEL]
    zero = np.zeros(3)
    pos, vel = np.empty(3), np.empty(3)
    pos[0], pos[1], pos[2] = c[0], c[1], z
    vel[0], vel[1], vel[2] = cv[0], cv[1], zd
    n = com_rows(kin, g_com, pos, vel, zero, ri, rf, n, errs, 0)
    pelvis_yaw = math.atan2(kin[KIN_R + 1, 0], kin[KIN_R, 0])
    n = pelvis_rows(kin, v, g_pelvis, pelvis_yaw, yaw_rate, ri, rf, n, errs, 1)
    sw = 1 - stance
    about = np.empty(3)
    if single:
        n = foot_position_rows(kin, jc_dot_v, sw, g_foot, swing_ref[0], swing_ref[1],
                               swing_ref[2], ri, rf, n, errs, 2)
        n = foot_pitch_rows(kin, jc_dot_v, sw, g_toe, toe, ri, rf, n, errs, 3)
        n = joint_row(q, v, hip_qpos, hip_dof, g_hip, 0.0, ri, rf, n, errs, 4)
        if ankle:
            f, r = kin[KIN_P_CONTACT + 2 * stance], kin[KIN_P_CONTACT + 2 * stance + 1]
            for a in range(3):
                about[a] = 0.5 * (f[a] + r[a])
            moment_row(kin, moment_rows[0], 2 * stance, 2 * stance + 1, about,
                       -math.sin(yaw), math.cos(yaw), 0.0)
    elif cop_f >= 0.0:
        tf, tr = kin[KIN_P_CONTACT + 2 * sw], kin[KIN_P_CONTACT + 2 * sw + 1]
        lf, lr = kin[KIN_P_CONTACT + 2 * stance], kin[KIN_P_CONTACT + 2 * stance + 1]
        for a in range(3):
            p_minus = 0.5 * (tf[a] + tr[a])
            p_plus = 0.5 * (lf[a] + lr[a])
            about[a] = p_minus + cop_f * (p_plus - p_minus)
        cy, sy = math.cos(yaw), math.sin(yaw)
        moment_row(kin, moment_rows[0], 0, 3, about, cy, sy, 0.0)
        moment_row(kin, moment_rows[1], 0, 3, about, -sy, cy, 0.0)
    return n
