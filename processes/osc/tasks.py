"""OSC task definitions and the gains file (Tables VI-VII): task-space PD rows for the QP (14a).

Every task turns a desired output (position, velocity, feed-forward acceleration) into rows of
``J dv + Jdot v ~= ydd_cmd`` with ``ydd_cmd = ydd_des + Kp (y_des - y) + Kd (yd_des - yd)``
(Section III-E) and appends them to a ``TaskRows`` stack with its weights ``W``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from runtime.errors import ConfigError

from .model import CassieModel
from .qp import ROW_COM, ROW_CONTACT, ROW_DOF, QpWeights, TaskRows

DEFAULT_GAINS_FILE = Path(__file__).resolve().parents[2] / "hw_config" / "gains" / "osc.yaml"


@dataclass
class Gains:
    """Weight and PD gains of one task, one entry per task axis."""

    w: np.ndarray
    kp: np.ndarray
    kd: np.ndarray

    def __post_init__(self) -> None:
        self.refresh()

    def refresh(self) -> None:
        """Update the float-list copies used on the hot path (call after editing the arrays)."""
        self.w_list = [float(x) for x in self.w]
        self.kp_list = [float(x) for x in self.kp]
        self.kd_list = [float(x) for x in self.kd]
        self.active = [a for a, x in enumerate(self.w_list) if x > 0.0]


@dataclass
class WalkingParams:
    """Walking tasks (Table VII) and the output-synthesis constants of Section V."""

    pelvis: Gains
    com: Gains
    swing_foot: Gains
    toe: Gains
    hip_yaw: Gains
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


@dataclass
class StandingParams:
    """Standing: CoM over the centre of the feet, pelvis level, hip yaw straight."""

    com: Gains
    pelvis: Gains
    hip_yaw: Gains
    com_height: float = 0.80
    com_offset_x: float = 0.0  # CoM target ahead of the feet's centre (m)
    height_rate: float = 0.1  # m/s ramp of the CoM height target from its start value
    xy_ramp_s: float = 1.0  # s to move the CoM x, y target from its start to the feet's centre


@dataclass
class SafetyParams:
    """Fault thresholds and the safe-mode joint damping (joint-side N m s/rad)."""

    fall_height: float = 0.6
    plan_timeout_s: float = 0.2
    damping: np.ndarray = field(
        default_factory=lambda: np.array([10.0, 10.0, 10.0, 10.0, 2.0] * 2)
    )


SPRING_MODES = ("rigid_swing", "measured")
SWING_TOE_MODES = ("plane", "level")


@dataclass
class OscParams:
    """Everything the OSC reads from ``hw_config/gains/osc.yaml``."""

    qp: QpWeights
    walking: WalkingParams
    standing: StandingParams
    safety: SafetyParams
    #: "rigid_swing": the OSC sees the swing leg's leaf springs at zero deflection (its model
    #: holds them rigid, (14c)); "measured": every estimated deflection enters the kinematics
    springs: str = "rigid_swing"
    source: str = "<defaults>"

    @classmethod
    def from_yaml(cls, path: str | Path | None = None) -> OscParams:
        """Load and validate the gains file; a bad value raises ``ConfigError``."""
        p = Path(path) if path is not None else DEFAULT_GAINS_FILE
        try:
            raw = yaml.safe_load(p.read_text(encoding="utf-8"))
        except OSError as e:
            raise ConfigError(str(p), "<file>", f"cannot read: {e}", "a readable YAML file") from e
        except yaml.YAMLError as e:
            raise ConfigError(str(p), "<file>", f"not valid YAML: {e}") from e
        if not isinstance(raw, dict):
            raise ConfigError(str(p), "<root>", "expected a mapping",
                              "qp, walking, standing, safety")
        return _parse(raw, str(p))


# ---------------------------------------------------------------------- parsing
def _section(raw: dict[str, Any], key: str, file: str, prefix: str = "") -> dict[str, Any]:
    v = raw.get(key)
    if not isinstance(v, dict):
        raise ConfigError(file, prefix + key, "missing or not a mapping")
    return v


def _num(raw: dict[str, Any], key: str, file: str, prefix: str, lo: float = 0.0,
         hi: float = math.inf, default: float | None = None) -> float:
    if key not in raw:
        if default is None:
            raise ConfigError(file, prefix + key, "missing", f"a number in [{lo}, {hi}]")
        return default
    v = raw[key]
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(float(v)):
        raise ConfigError(file, prefix + key, f"not a finite number: {v!r}", f"[{lo}, {hi}]")
    if not lo <= float(v) <= hi:
        raise ConfigError(file, prefix + key, f"{v} out of range", f"[{lo}, {hi}]")
    return float(v)


def _vec(v: Any, n: int, file: str, key: str, lo: float = 0.0) -> np.ndarray:
    if isinstance(v, (int, float)) and not isinstance(v, bool):
        v = [v] * n
    if not isinstance(v, list) or len(v) != n:
        raise ConfigError(file, key, f"expected {n} numbers, got {v!r}", f"a list of {n} numbers")
    out = np.zeros(n)
    for i, x in enumerate(v):
        if isinstance(x, bool) or not isinstance(x, (int, float)) or not math.isfinite(float(x)):
            raise ConfigError(file, f"{key}[{i}]", f"not a finite number: {x!r}")
        if float(x) < lo:
            raise ConfigError(file, f"{key}[{i}]", f"{x} is negative", f">= {lo}")
        out[i] = float(x)
    return out


def _gains(raw: dict[str, Any], key: str, n: int, file: str, prefix: str) -> Gains:
    g = _section(raw, key, file, prefix)
    k = prefix + key + "."
    for name in g:
        if name not in ("w", "kp", "kd"):
            raise ConfigError(file, k + name, "unknown key", "w, kp, kd")
    return Gains(*(_vec(g.get(a, 0.0), n, file, k + a) for a in ("w", "kp", "kd")))


def _only(raw: dict[str, Any], allowed: tuple[str, ...], file: str, prefix: str) -> None:
    """Reject unknown keys (a typo must not silently fall back to a default)."""
    for key in raw:
        if key not in allowed:
            raise ConfigError(file, prefix + str(key), "unknown key", ", ".join(allowed))


def _parse(raw: dict[str, Any], file: str) -> OscParams:
    for key in raw:
        if key not in ("qp", "walking", "standing", "safety", "springs"):
            raise ConfigError(file, key, "unknown section",
                              "qp, walking, standing, safety, springs")
    springs = raw.get("springs", "rigid_swing")
    if springs not in SPRING_MODES:
        raise ConfigError(file, "springs", f"{springs!r} is not a spring mode",
                          ", ".join(SPRING_MODES))
    q = _section(raw, "qp", file)
    qw = QpWeights()
    names = {f.name for f in fields(QpWeights)}
    for key in q:
        if key not in names:
            raise ConfigError(file, "qp." + key, "unknown key", ", ".join(sorted(names)))
    for f in fields(QpWeights):
        hi = 2.0 if f.name == "mu" else math.inf
        setattr(qw, f.name, _num(q, f.name, file, "qp.", 0.0, hi, getattr(qw, f.name)))
    if qw.mu <= 0.0:
        raise ConfigError(file, "qp.mu", "must be positive", "(0, 2]")

    w = _section(raw, "walking", file)
    pw = "walking."
    _only(w, ("pelvis", "com", "swing_foot", "toe", "hip_yaw", "ankle_torque_weight",
              "com_height", "com_filter_hz", "com_clip", "swing_clearance", "swing_degree",
              "swing_step_up_min", "swing_step_up_clearance", "swing_step_up_height",
              "swing_lift_tau", "swing_approach_tau", "swing_toe"),
          file, pw)
    toe_mode = w.get("swing_toe", "plane")
    if toe_mode not in SWING_TOE_MODES:
        raise ConfigError(file, pw + "swing_toe", f"{toe_mode!r} is not a swing toe mode",
                          ", ".join(SWING_TOE_MODES))
    walking = WalkingParams(
        pelvis=_gains(w, "pelvis", 3, file, pw),
        com=_gains(w, "com", 3, file, pw),
        swing_foot=_gains(w, "swing_foot", 3, file, pw),
        toe=_gains(w, "toe", 1, file, pw),
        hip_yaw=_gains(w, "hip_yaw", 1, file, pw),
        ankle_torque_weight=_num(w, "ankle_torque_weight", file, pw, default=10.0),
        com_height=_num(w, "com_height", file, pw, 0.5, 1.1, 0.85),
        com_filter_hz=_num(w, "com_filter_hz", file, pw, 1.0, 1000.0, 100.0),
        com_clip=_num(w, "com_clip", file, pw, 0.0, 0.2, 0.025),
        swing_clearance=_num(w, "swing_clearance", file, pw, 0.0, 0.4, 0.15),
        swing_degree=int(_num(w, "swing_degree", file, pw, 7, 12, 8)),
        swing_step_up_min=_num(w, "swing_step_up_min", file, pw, 0.0, 1.0, 0.0),
        swing_step_up_clearance=_num(w, "swing_step_up_clearance", file, pw, 0.0, 0.4, 0.06),
        swing_step_up_height=_num(w, "swing_step_up_height", file, pw, 0.0, 0.2, 0.04),
        swing_lift_tau=_num(w, "swing_lift_tau", file, pw, 0.1, 0.45, 0.25),
        swing_approach_tau=_num(w, "swing_approach_tau", file, pw, 0.55, 0.9, 0.8),
        swing_toe=str(toe_mode),
    )
    s = _section(raw, "standing", file)
    ps = "standing."
    _only(s, ("com", "pelvis", "hip_yaw", "com_height", "com_offset_x", "height_rate",
              "xy_ramp_s"), file, ps)
    standing = StandingParams(
        com=_gains(s, "com", 3, file, ps),
        pelvis=_gains(s, "pelvis", 3, file, ps),
        hip_yaw=_gains(s, "hip_yaw", 1, file, ps),
        com_height=_num(s, "com_height", file, ps, 0.5, 1.1, 0.80),
        com_offset_x=_num(s, "com_offset_x", file, ps, -0.1, 0.1, 0.0),
        height_rate=_num(s, "height_rate", file, ps, 0.0, 1.0, 0.1),
        xy_ramp_s=_num(s, "xy_ramp_s", file, ps, 0.0, 10.0, 1.0),
    )
    f = raw.get("safety", {}) or {}
    if not isinstance(f, dict):
        raise ConfigError(file, "safety", "not a mapping")
    _only(f, ("fall_height", "plan_timeout_s", "damping"), file, "safety.")
    safety = SafetyParams(
        fall_height=_num(f, "fall_height", file, "safety.", 0.0, 1.0, 0.6),
        plan_timeout_s=_num(f, "plan_timeout_s", file, "safety.", 0.001, 5.0, 0.2),
        damping=_vec(f.get("damping", [10.0, 10.0, 10.0, 10.0, 2.0] * 2), 10, file,
                     "safety.damping"),
    )
    return OscParams(qp=qw, walking=walking, standing=standing, safety=safety,
                     springs=str(springs), source=file)


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
        self.errors.append(math.hypot(*err))


def rot_log_list(R: list[list[float]]) -> tuple[float, float, float]:
    """Rotation vector (axis * angle) of a rotation matrix given as nested lists."""
    c = max(-1.0, min(1.0, 0.5 * (R[0][0] + R[1][1] + R[2][2] - 1.0)))
    ang = math.acos(c)
    vx, vy, vz = R[2][1] - R[1][2], R[0][2] - R[2][0], R[1][0] - R[0][1]
    k = 0.5 if ang < 1e-6 else ang / (2.0 * math.sin(ang))
    return vx * k, vy * k, vz * k


class PelvisOrientationTask:
    """Pelvis roll/pitch/yaw (Tables VI-VII) on the body-frame angular acceleration dv[3:6].

    MuJoCo's free joint velocity v[3:6] is the body-frame angular velocity, so J is a selector
    and Jdot v = 0. The error is the body-frame rotation vector from R to R_des = Rz(yaw_des);
    a yaw Kp of 0 (walking) leaves only yaw-rate tracking. 3-vectors use float arithmetic
    (a numpy call costs more than the whole computation here).
    """

    def __init__(self, nv: int) -> None:
        self.J = np.zeros((3, nv))
        self.J[0, 3] = self.J[1, 4] = self.J[2, 5] = 1.0

    def add(self, rows: TaskRows, log: TaskLog, m: CassieModel, v: np.ndarray, gains: Gains,
            yaw_des: float, yaw_rate_des: float) -> None:
        R = m.R_list  # pelvis rotation (body -> world) as nested lists
        cy, sy = math.cos(yaw_des), math.sin(yaw_des)
        # E = R^T Rz(yaw_des)
        r0, r1, r2 = R
        E = [[r0[0] * cy + r1[0] * sy, -r0[0] * sy + r1[0] * cy, r2[0]],
             [r0[1] * cy + r1[1] * sy, -r0[1] * sy + r1[1] * cy, r2[1]],
             [r0[2] * cy + r1[2] * sy, -r0[2] * sy + r1[2] * cy, r2[2]]]
        e = rot_log_list(E)
        w = v[3:6].tolist()
        kp, kd, wt = gains.kp_list, gains.kd_list, gains.w_list
        for a in range(3):
            # desired body rate: the world z rate expressed in the body frame (R^T e_z);
            # J selects the body-frame angular velocity dv[3 + a], Jdot v = 0
            ydd = kp[a] * e[a] + kd[a] * (R[2][a] * yaw_rate_des - w[a])
            rows.add_row(ROW_DOF + 3 + a, 1.0, ydd, wt[a])
        log.add("pelvis_rpy", *e)


def add_com_task(rows: TaskRows, log: TaskLog, m: CassieModel, gains: Gains,
                 pos_des: list[float], vel_des: list[float], acc_des: list[float],
                 name: str = "com") -> None:
    """CoM position rows (world frame), skipping axes with zero weight."""
    c, cv, cd = m.com_l, m.com_vel_l, m.com_dot_v_l
    errs = []
    for a in gains.active:
        e = pos_des[a] - c[a]
        errs.append(e)
        ydd = acc_des[a] + gains.kp_list[a] * e + gains.kd_list[a] * (vel_des[a] - cv[a])
        rows.add_row(ROW_COM + a, 1.0, ydd - cd[a], gains.w_list[a])  # J_com[a], Jdot v
    log.add(name, *errs)


def add_foot_position_task(rows: TaskRows, log: TaskLog, m: CassieModel, side: int, gains: Gains,
                           pos: list[float], vel: list[float], acc: list[float]) -> None:
    """Swing-foot position (midpoint of the blade's two contact points, world frame)."""
    f, r = m.p_contact_l[2 * side], m.p_contact_l[2 * side + 1]
    fv, rv = m.v_contact_l[2 * side], m.v_contact_l[2 * side + 1]
    jd = m.Jc_dot_v_l[6 * side : 6 * side + 6]
    kp, kd, w = gains.kp_list, gains.kd_list, gains.w_list
    e = [pos[a] - 0.5 * (f[a] + r[a]) for a in range(3)]
    j0 = ROW_CONTACT + 6 * side  # front point's rows; the rear point's follow
    for a in range(3):
        b = (acc[a] + kp[a] * e[a] + kd[a] * (vel[a] - 0.5 * (fv[a] + rv[a]))
             - 0.5 * (jd[a] + jd[a + 3]))
        rows.add_row(j0 + a, 0.5, b, w[a], j0 + 3 + a, 1.0)  # J of the midpoint
    log.add("swing_foot", *e)


def add_foot_pitch_task(rows: TaskRows, log: TaskLog, m: CassieModel, side: int, gains: Gains,
                        pitch_des: float, name: str = "swing_toe") -> None:
    """Toe angle as the world pitch of the foot blade (Section V-C: foot at atan(k_x)).

    pitch = asin(dz / L) with dz the height of the front point over the rear one, so
    d(pitch)/dt = (Jz_front - Jz_rear) v / (L cos(pitch)).
    """
    i = 6 * side
    pitch = m.foot_pitch(side)
    f, r = m.p_contact_l[2 * side], m.p_contact_l[2 * side + 1]
    L = math.sqrt((f[0] - r[0]) ** 2 + (f[1] - r[1]) ** 2 + (f[2] - r[2]) ** 2)
    scale = 1.0 / (L * max(math.cos(pitch), 0.2))
    jdv = (m.Jc_dot_v_l[i + 2] - m.Jc_dot_v_l[i + 5]) * scale
    rate = (m.v_contact_l[2 * side][2] - m.v_contact_l[2 * side + 1][2]) * scale
    e = pitch_des - pitch
    ydd = gains.kp_list[0] * e - gains.kd_list[0] * rate
    # J = (Jz_front - Jz_rear) * scale
    rows.add_row(ROW_CONTACT + i + 2, scale, ydd - jdv, gains.w_list[0], ROW_CONTACT + i + 5,
                 -1.0)
    log.add(name, e)


def add_joint_task(rows: TaskRows, log: TaskLog, m: CassieModel, q: np.ndarray, v: np.ndarray,
                   qpos: int, dof: int, gains: Gains, q_des: float, name: str) -> None:
    """One joint angle (hip yaw): a selector row, Jdot v = 0."""
    e = q_des - float(q[qpos])
    ydd = gains.kp_list[0] * e - gains.kd_list[0] * float(v[dof])
    rows.add_row(ROW_DOF + dof, 1.0, ydd, gains.w_list[0])
    log.add(name, e)
