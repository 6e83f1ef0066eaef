"""Straightforward Python references of the OSC task rows (the code the compiled task kernels
replaced, kept verbatim apart from this header): each task appends rows to a TaskRows stack
and its error norm to a TaskLog. Tests compare the compiled kernels against these."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from processes.osc.model import CassieModel
from processes.osc.qp import ROW_COM, ROW_CONTACT, ROW_DOF, TaskRows
from processes.osc.tasks import TaskGains as Gains


class TaskLog:
    """Names and tracking-error norms of the tasks of one tick."""

    def __init__(self) -> None:
        self.names: list[str] = []
        self.errors: list[float] = []

    def add(self, name: str, *err: float) -> None:
        self.names.append(name)
        self.errors.append(math.sqrt(sum(e * e for e in err)))


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


def moment_row(row: np.ndarray, points: Any, idx: Any, about: Any,
               axis: tuple[float, float, float]) -> None:
    """The moment along ``axis`` about ``about`` of the forces at ``points[idx]``."""
    vals = [0.0] * len(row)
    ax, ay, az = axis
    a0, a1, a2 = about
    for i in idx:
        p = points[i]
        rx, ry, rz = p[0] - a0, p[1] - a1, p[2] - a2
        vals[3 * i : 3 * i + 3] = (ay * rz - az * ry, az * rx - ax * rz, ax * ry - ay * rx)
    row[:] = vals
