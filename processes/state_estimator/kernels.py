"""Every compiled kernel of the state estimator, and the whole per-packet step as one kernel.

numba caches each kernel on disk and revalidates the cache against the file the kernel is
defined in, not the files of the kernels it calls: the fused step (``run``) calls all of the
others, so they all live in this one file (a change to any of them recompiles the step).

The per-stage kernels (leg kinematics, InEKF propagation and correction, range check, sole
points, foot speeds) are used by the modular estimator (``kinematics.LegKinematics``,
``inekf.ContactInEKF``, ``estimator.CassieEstimator`` with ``fused=False``), which is the
reference the fused step is tested against. ``run`` does one packet's whole work in one call:
packet validation and range checks, leg kinematics (MuJoCo's ``mj_kinematics``, ``mj_comPos``,
``mj_comVel`` and ``mj_subtreeVel`` called through their C entry points), InEKF propagation,
contact, correction, the full ``q``/``v``, and on the laptop's packets the CoM, momentum and
ALIP Kalman filter; it works in place on a few packed buffers (layout below) whose slices the
Python objects hold as views. On the live 2 kHz path, Python's and numba's per-call costs on
small arrays were most of a tick (and on this VM every wake-up runs with cold caches, so a
tick's cost grows with the code and objects it touches).
"""

from __future__ import annotations

import ctypes
import glob
import math
import os

import mujoco
import numba
import numpy as np
from llvmlite import ir
from numba import types
from numba.extending import intrinsic

from runtime.cassie_packets import (
    NUM_JOINTS,
    NUM_MOTORS,
    OUTPUT_LAYOUT,
    OUTPUT_SIZE,
)

_jit = numba.njit(cache=True, nogil=True)
_fjit = numba.njit(cache=True, nogil=True, error_model="numpy")  # the InEKF: NaN, not raise

#: InEKF error-state dimension: rotation, velocity, position, two contact points
DIM = 15
#: sine of the foot pitch above which the heel or toe bears the load, and back to mid-foot
PITCH_ON = 0.03
PITCH_OFF = 0.015


# -- InEKF (processes/state_estimator/inekf.py) ----------------------------------------------
@_fjit
def _so3_coeffs(x: float, y: float, z: float) -> tuple[float, float, float]:
    """(sin t / t, (1 - cos t) / t^2, (t - sin t) / t^3) for t = |(x, y, z)|, series near 0."""
    th2 = x * x + y * y + z * z
    if th2 < 1e-12:
        return 1.0 - th2 / 6.0, 0.5 - th2 / 24.0, 1.0 / 6.0 - th2 / 120.0
    th = math.sqrt(th2)
    sn, co = math.sin(th), math.cos(th)
    return sn / th, (1.0 - co) / th2, (th - sn) / (th2 * th)


@_fjit
def _i_plus(out: np.ndarray, a: float, b: float, x: float, y: float, z: float) -> None:
    """out = I + a [w]x + b [w]x^2 (Rodrigues-type series), w = (x, y, z)."""
    xx, yy, zz, xy, xz, yz = x * x, y * y, z * z, x * y, x * z, y * z
    out[0, 0], out[0, 1], out[0, 2] = 1.0 - b * (yy + zz), -a * z + b * xy, a * y + b * xz
    out[1, 0], out[1, 1], out[1, 2] = a * z + b * xy, 1.0 - b * (xx + zz), -a * x + b * yz
    out[2, 0], out[2, 1], out[2, 2] = -a * y + b * xz, a * x + b * yz, 1.0 - b * (xx + yy)


@_fjit
def _skew_rows(n: np.ndarray, r0: int, w: np.ndarray) -> None:
    """Rows r0..r0+2 of ``n`` (.., 3) := [w]x."""
    x, y, z = w[0], w[1], w[2]
    n[r0, 0], n[r0, 1], n[r0, 2] = 0.0, -z, y
    n[r0 + 1, 0], n[r0 + 1, 1], n[r0 + 1, 2] = z, 0.0, -x
    n[r0 + 2, 0], n[r0 + 2, 1], n[r0 + 2, 2] = -y, x, 0.0


@_fjit
def _propagate(R: np.ndarray, v: np.ndarray, p: np.ndarray, d: np.ndarray, P: np.ndarray,
               gyro: np.ndarray, accel: np.ndarray, dt: float, g: np.ndarray,
               var_g: float, var_a: float, var_f0: float, var_f1: float,
               scratch: np.ndarray) -> None:
    """One IMU step of the mean (Hartley eq. (14)-(16)) and covariance (eq. (26)-(27))."""
    # a = R accel + g, with R before the step
    a = np.empty(3)
    for i in range(3):
        a[i] = R[i, 0] * accel[0] + R[i, 1] * accel[1] + R[i, 2] * accel[2] + g[i]
    # process noise Ad_X Q Ad_X^T for isotropic blocks: s_g^2 N N^T, N = [I; v^; p^; dL^; dR^]
    # (the R R^T in between cancels), plus s_a^2 I on v and the contact noise on each foot
    N = np.zeros((DIM, 3))
    N[0, 0] = N[1, 1] = N[2, 2] = 1.0
    _skew_rows(N, 3, v)
    _skew_rows(N, 6, p)
    _skew_rows(N, 9, d[0])
    _skew_rows(N, 12, d[1])
    qg = var_g * dt
    for i in range(DIM):
        for j in range(i, DIM):
            s = qg * (N[i, 0] * N[j, 0] + N[i, 1] * N[j, 1] + N[i, 2] * N[j, 2])
            P[i, j] += s
            if j != i:
                P[j, i] += s
    for i in range(3):
        P[3 + i, 3 + i] += var_a * dt
        P[9 + i, 9 + i] += var_f0 * dt
        P[12 + i, 12 + i] += var_f1 * dt
    # P+ = Phi P Phi^T with Phi = I + A dt + A^2 dt^2 / 2 (A^3 = 0): Phi differs from I only
    # in the (v, R) block G dt, the (p, R) block G dt^2 / 2 and the (p, v) block I dt, where
    # G = [g]x; apply it to the rows, then to the columns
    h2 = 0.5 * dt * dt
    G = scratch
    G[:] = 0.0
    G[0, 1], G[0, 2] = -g[2], g[1]
    G[1, 0], G[1, 2] = g[2], -g[0]
    G[2, 0], G[2, 1] = -g[1], g[0]
    for c in range(DIM):  # rows: v += G dt rot; p += G dt^2/2 rot + dt v (old v)
        r0, r1, r2 = P[0, c], P[1, c], P[2, c]
        v0, v1, v2 = P[3, c], P[4, c], P[5, c]
        for i in range(3):
            gr = G[i, 0] * r0 + G[i, 1] * r1 + G[i, 2] * r2
            P[3 + i, c] += dt * gr
            P[6 + i, c] += h2 * gr
        P[6, c] += dt * v0
        P[7, c] += dt * v1
        P[8, c] += dt * v2
    for r in range(DIM):  # columns, the same
        r0, r1, r2 = P[r, 0], P[r, 1], P[r, 2]
        v0, v1, v2 = P[r, 3], P[r, 4], P[r, 5]
        for i in range(3):
            gr = G[i, 0] * r0 + G[i, 1] * r1 + G[i, 2] * r2
            P[r, 3 + i] += dt * gr
            P[r, 6 + i] += h2 * gr
        P[r, 6] += dt * v0
        P[r, 7] += dt * v1
        P[r, 8] += dt * v2
    # mean: R+ = R Exp(w dt), v+ = v + a dt, p+ = p + v dt + a dt^2 / 2
    for i in range(3):
        p[i] += v[i] * dt + h2 * a[i]
        v[i] += a[i] * dt
    wx, wy, wz = gyro[0] * dt, gyro[1] * dt, gyro[2] * dt
    ca, cb, _ = _so3_coeffs(wx, wy, wz)
    dR = np.empty((3, 3))
    _i_plus(dR, ca, cb, wx, wy, wz)
    for i in range(3):
        r0, r1, r2 = R[i, 0], R[i, 1], R[i, 2]
        for j in range(3):
            R[i, j] = r0 * dR[0, j] + r1 * dR[1, j] + r2 * dR[2, j]


@_fjit
def _apply_update(R: np.ndarray, v: np.ndarray, p: np.ndarray, d: np.ndarray, P: np.ndarray,
                  PHt: np.ndarray, S: np.ndarray, z: np.ndarray) -> None:
    """The InEKF correction given ``P H^T``, the innovation covariance ``S`` and the innovation
    ``z`` (Hartley eq. (37)-(39)): gain, the group update ``X+ = exp(K z) X``, ``P+``."""
    m = z.shape[0]
    # K = P H^T S^-1 by Cholesky (S = L L^T, symmetric positive definite): K^T = S^-1 PHt^T
    L = np.zeros((m, m))
    for j in range(m):
        acc = S[j, j]
        for c in range(j):
            acc -= L[j, c] * L[j, c]
        L[j, j] = math.sqrt(acc)
        for i in range(j + 1, m):
            acc = S[i, j]
            for c in range(j):
                acc -= L[i, c] * L[j, c]
            L[i, j] = acc / L[j, j]
    KT = np.empty((m, DIM))
    for col in range(DIM):
        for i in range(m):  # forward: L y = PHt[col]
            acc = PHt[col, i]
            for c in range(i):
                acc -= L[i, c] * KT[c, col]
            KT[i, col] = acc / L[i, i]
        for i in range(m - 1, -1, -1):  # backward: L^T x = y
            acc = KT[i, col]
            for c in range(i + 1, m):
                acc -= L[c, i] * KT[c, col]
            KT[i, col] = acc / L[i, i]
    delta = np.zeros(DIM)  # K z
    for i in range(DIM):
        for c in range(m):
            delta[i] += KT[c, i] * z[c]
    # X+ = exp(delta) X (left multiplication for the right-invariant error): R+ = Exp(phi) R,
    # and each column x of (v, p, dL, dR) becomes Exp(phi) x + J_l(phi) xi_x
    ca, cb, cc = _so3_coeffs(delta[0], delta[1], delta[2])
    dR = np.empty((3, 3))
    jl = np.empty((3, 3))
    _i_plus(dR, ca, cb, delta[0], delta[1], delta[2])
    _i_plus(jl, cb, cc, delta[0], delta[1], delta[2])
    for j in range(3):
        r0, r1, r2 = R[0, j], R[1, j], R[2, j]
        for i in range(3):
            R[i, j] = dR[i, 0] * r0 + dR[i, 1] * r1 + dR[i, 2] * r2
    x = np.empty(3)
    for b in range(4):
        o = 3 + 3 * b
        for i in range(3):
            x[i] = v[i] if b == 0 else p[i] if b == 1 else d[b - 2, i]
        for i in range(3):
            y = (dR[i, 0] * x[0] + dR[i, 1] * x[1] + dR[i, 2] * x[2]
                 + jl[i, 0] * delta[o] + jl[i, 1] * delta[o + 1] + jl[i, 2] * delta[o + 2])
            if b == 0:
                v[i] = y
            elif b == 1:
                p[i] = y
            else:
                d[b - 2, i] = y
    # P+ = (I - K H) P = P - K (P H^T)^T, kept symmetric
    for i in range(DIM):
        for j in range(i, DIM):
            acc = 0.0
            for c in range(m):
                acc += PHt[i, c] * KT[c, j] + PHt[j, c] * KT[c, i]
            a = 0.5 * (P[i, j] + P[j, i] - acc)
            P[i, j] = a
            P[j, i] = a


@_fjit
def _correct(R: np.ndarray, v: np.ndarray, p: np.ndarray, d: np.ndarray, P: np.ndarray,
             h: np.ndarray, c0: bool, c1: bool, kin_var: float) -> None:
    """Leg-kinematics update (Hartley Sec. 6, eq. (36)-(40)) for the feet in contact."""
    feet = [k for k, on in ((0, c0), (1, c1)) if on]  # measured feet, in stacking order
    m = 3 * len(feet)
    PHt = np.empty((DIM, m))  # P H^T, H = [0, 0, -I, +I at d_k] per contact foot
    z = np.empty(m)  # innovation R h_k + p - d_k, stacked
    for b, k in enumerate(feet):
        f, col = 9 + 3 * k, 3 * b
        for j in range(3):
            for i in range(DIM):
                PHt[i, col + j] = P[i, f + j] - P[i, 6 + j]
            z[col + j] = (R[j, 0] * h[k, 0] + R[j, 1] * h[k, 1] + R[j, 2] * h[k, 2]
                          + p[j] - d[k, j])
    S = np.empty((m, m))  # H P H^T + N, N = s_k^2 I (R N R^T = N: isotropic)
    for b, k in enumerate(feet):
        f, col = 9 + 3 * k, 3 * b
        for j in range(3):
            for c in range(m):
                S[col + j, c] = PHt[f + j, c] - PHt[6 + j, c]
            S[col + j, col + j] += kin_var
    _apply_update(R, v, p, d, P, PHt, S, z)


@_fjit
def _correct_still(R: np.ndarray, v: np.ndarray, p: np.ndarray, d: np.ndarray, P: np.ndarray,
                   var: float) -> None:
    """Zero-velocity update of a robot held still with no foot on the ground (hung from the
    start-up holder or a gantry): the body-frame IMU velocity ``R^T v`` is measured as 0, a
    right-invariant observation like the leg kinematics (``Y = X^-1 b``, ``b`` the velocity
    column), so ``H = [0, I, 0, 0, 0]`` is constant and the innovation is ``R 0 - v = -v``.
    Without it the dead-reckoned covariance grows as t^4 while the robot hangs (position
    std ~40 m after 20 s) and the first touchdown after a long hold throws the estimate
    metres off (a fresh clone's launch, where the OSC compiles for a minute, fell so)."""
    PHt = np.empty((DIM, 3))
    z = np.empty(3)
    S = np.empty((3, 3))
    for j in range(3):
        for i in range(DIM):
            PHt[i, j] = P[i, 3 + j]
        z[j] = -v[j]
    for i in range(3):
        for j in range(3):
            S[i, j] = PHt[3 + i, j]
        S[i, i] += var
    _apply_update(R, v, p, d, P, PHt, S, z)


@_jit
def _imu_at_rest(gyro: np.ndarray, accel: np.ndarray, g: float, gyro_max: float,
                          accel_tol: float) -> bool:
    """Whether one IMU sample reads at rest: no rotation and a specific force of ``g``."""
    w2 = gyro[0] * gyro[0] + gyro[1] * gyro[1] + gyro[2] * gyro[2]
    a = math.sqrt(accel[0] * accel[0] + accel[1] * accel[1] + accel[2] * accel[2])
    return w2 < gyro_max * gyro_max and abs(a - g) < accel_tol


# -- leg kinematics (processes/state_estimator/kinematics.py): at 2 kHz, Python and numpy
# per-call costs on 3-vectors were most of the kinematics' time ---------------------------
@_jit
def _assemble(q: np.ndarray, v: np.ndarray, motor_pos: np.ndarray, motor_vel: np.ndarray,
              joint_pos: np.ndarray, joint_vel: np.ndarray, motor_q: np.ndarray,
              motor_d: np.ndarray, joint_q: np.ndarray, joint_d: np.ndarray,
              ach_q: np.ndarray, pla_q: np.ndarray, qpos: np.ndarray) -> None:
    """The measured joints into ``q``/``v`` (base at the origin, rods at zero), and ``qpos``."""
    v[:] = 0.0
    for i in range(motor_q.size):
        q[motor_q[i]] = motor_pos[i]
        v[motor_d[i]] = motor_vel[i]
    for i in range(joint_q.size):
        q[joint_q[i]] = joint_pos[i]
        v[joint_d[i]] = joint_vel[i]
    q[0:3] = 0.0
    q[3], q[4], q[5], q[6] = 1.0, 0.0, 0.0, 0.0
    for k in range(2):
        i = ach_q[k]
        q[i], q[i + 1], q[i + 2], q[i + 3] = 1.0, 0.0, 0.0, 0.0
        q[pla_q[k]] = 0.0
    qpos[:] = q


@_jit
def _solve_rods(xpos: np.ndarray, xmat: np.ndarray, q: np.ndarray, qpos: np.ndarray,
                rod_body: np.ndarray, tgt_body: np.ndarray, tgt_off: np.ndarray,
                ach_dir: np.ndarray, pla_axis: np.ndarray, pla_tip_proj: np.ndarray,
                ach_q: np.ndarray, pla_q: np.ndarray) -> None:
    """Closed-form rod angles so each rod tip meets its closure point (after pass 1).

    Rods 0-1 are the achilles rods (ball joint: the shortest rotation taking the tip
    direction onto the target direction), 2-3 the plantar rods (hinge: the signed angle
    between the two directions projected on the hinge plane). Writes ``q`` and ``qpos``.
    """
    for k in range(4):
        g = tgt_off[k]
        a, b, xr, r = xmat[tgt_body[k]], xpos[tgt_body[k]], xpos[rod_body[k]], xmat[rod_body[k]]
        # target point (world), minus the rod origin
        e0 = b[0] + a[0] * g[0] + a[1] * g[1] + a[2] * g[2] - xr[0]
        e1 = b[1] + a[3] * g[0] + a[4] * g[1] + a[5] * g[2] - xr[1]
        e2 = b[2] + a[6] * g[0] + a[7] * g[1] + a[8] * g[2] - xr[2]
        # u = R_rod^T e: the target in the rod's zero-angle frame
        u0 = r[0] * e0 + r[3] * e1 + r[6] * e2
        u1 = r[1] * e0 + r[4] * e1 + r[7] * e2
        u2 = r[2] * e0 + r[5] * e1 + r[8] * e2
        if k < 2:
            t0, t1, t2 = ach_dir[k, 0], ach_dir[k, 1], ach_dir[k, 2]
            n = math.sqrt(u0 * u0 + u1 * u1 + u2 * u2)
            u0, u1, u2 = u0 / n, u1 / n, u2 / n
            w = 1.0 + t0 * u0 + t1 * u1 + t2 * u2
            x = t1 * u2 - t2 * u1
            y = t2 * u0 - t0 * u2
            z = t0 * u1 - t1 * u0
            n = math.sqrt(w * w + x * x + y * y + z * z)
            i = ach_q[k]
            q[i], q[i + 1], q[i + 2], q[i + 3] = w / n, x / n, y / n, z / n
        else:
            a0, a1, a2 = pla_axis[k - 2, 0], pla_axis[k - 2, 1], pla_axis[k - 2, 2]
            p0, p1, p2 = pla_tip_proj[k - 2, 0], pla_tip_proj[k - 2, 1], pla_tip_proj[k - 2, 2]
            s = u0 * a0 + u1 * a1 + u2 * a2
            u0, u1, u2 = u0 - s * a0, u1 - s * a1, u2 - s * a2
            c0 = p1 * u2 - p2 * u1
            c1 = p2 * u0 - p0 * u2
            c2 = p0 * u1 - p1 * u0
            q[pla_q[k - 2]] = math.atan2(c0 * a0 + c1 * a1 + c2 * a2,
                                         p0 * u0 + p1 * u1 + p2 * u2)
    qpos[:] = q


@_jit
def _feet_and_springs(xpos: np.ndarray, xmat: np.ndarray, foot_body: np.ndarray,
                      foot_local: np.ndarray, foot_pos: np.ndarray, foot_axis: np.ndarray,
                      q: np.ndarray, spring_q: np.ndarray, spring_ref: np.ndarray,
                      spring_defl: np.ndarray) -> None:
    """Each foot's capsule centre and axis (pelvis frame), and the spring deflections."""
    for k in range(2):
        b = foot_body[k]
        r = xmat[b]
        for i in range(3):
            foot_pos[k, i] = xpos[b, i] + (r[3 * i] * foot_local[k, 0, 0]
                                           + r[3 * i + 1] * foot_local[k, 1, 0]
                                           + r[3 * i + 2] * foot_local[k, 2, 0])
            foot_axis[k, i] = (r[3 * i] * foot_local[k, 0, 1] + r[3 * i + 1] * foot_local[k, 1, 1]
                               + r[3 * i + 2] * foot_local[k, 2, 1])
        for j in range(2):
            spring_defl[k, j] = q[spring_q[k, j]] - spring_ref[k, j]


@_jit
def _foot_velocities(cvel: np.ndarray, subtree_com: np.ndarray, pelvis: int,
                     foot_body: np.ndarray, foot_pos: np.ndarray, foot_vel: np.ndarray) -> None:
    """Velocity of each foot's capsule centre relative to the pelvis (pelvis frame), from
    ``cvel`` with the base at rest: v + w x (p - c) at the tree's subtree CoM ``c``."""
    c0, c1, c2 = subtree_com[pelvis, 0], subtree_com[pelvis, 1], subtree_com[pelvis, 2]
    for k in range(2):
        w = cvel[foot_body[k]]
        e0, e1, e2 = foot_pos[k, 0] - c0, foot_pos[k, 1] - c1, foot_pos[k, 2] - c2
        foot_vel[k, 0] = w[3] + w[1] * e2 - w[2] * e1
        foot_vel[k, 1] = w[4] + w[2] * e0 - w[0] * e2
        foot_vel[k, 2] = w[5] + w[0] * e1 - w[1] * e0


@_jit
def _rod_velocities(xpos: np.ndarray, xmat: np.ndarray, cvel: np.ndarray,
                    subtree_com: np.ndarray, v: np.ndarray, pelvis: int, rod_body: np.ndarray,
                    tgt_body: np.ndarray, rod_tip: np.ndarray, tgt_off: np.ndarray,
                    pla_axis: np.ndarray, ach_d: np.ndarray, pla_d: np.ndarray) -> None:
    """Rod joint rates that keep the closures' relative velocity zero (min-norm for the
    achilles ball joint, whose spin about its own axis is not constrained).

    With the rod rates zero in ``cvel``, each tip moves rigidly with its parent; the rate
    must make up the difference ``dv`` to the target's velocity: for the ball joint
    ``w = r x dv / |r|^2`` (given to MuJoCo in the rod frame), for the hinge about ``a``
    ``qdot = (a x r).dv / |a x r|^2``.
    """
    c0, c1, c2 = subtree_com[pelvis, 0], subtree_com[pelvis, 1], subtree_com[pelvis, 2]
    for k in range(4):
        # tip offset r from the rod origin and target offset g from its body, world
        m, t = xmat[rod_body[k]], rod_tip[k]
        r0 = m[0] * t[0] + m[1] * t[1] + m[2] * t[2]
        r1 = m[3] * t[0] + m[4] * t[1] + m[5] * t[2]
        r2 = m[6] * t[0] + m[7] * t[1] + m[8] * t[2]
        a, g = xmat[tgt_body[k]], tgt_off[k]
        g0 = a[0] * g[0] + a[1] * g[1] + a[2] * g[2]
        g1 = a[3] * g[0] + a[4] * g[1] + a[5] * g[2]
        g2 = a[6] * g[0] + a[7] * g[1] + a[8] * g[2]
        # point velocities from cvel (rotation; linear at the subtree CoM): v + w x (p - c)
        w, p = cvel[rod_body[k]], xpos[rod_body[k]]
        e0, e1, e2 = p[0] + r0 - c0, p[1] + r1 - c1, p[2] + r2 - c2
        v0 = w[3] + w[1] * e2 - w[2] * e1
        v1 = w[4] + w[2] * e0 - w[0] * e2
        v2 = w[5] + w[0] * e1 - w[1] * e0
        w, p = cvel[tgt_body[k]], xpos[tgt_body[k]]
        e0, e1, e2 = p[0] + g0 - c0, p[1] + g1 - c1, p[2] + g2 - c2
        d0 = w[3] + w[1] * e2 - w[2] * e1 - v0
        d1 = w[4] + w[2] * e0 - w[0] * e2 - v1
        d2 = w[5] + w[0] * e1 - w[1] * e0 - v2
        if k < 2:
            n = r0 * r0 + r1 * r1 + r2 * r2
            w0 = (r1 * d2 - r2 * d1) / n
            w1 = (r2 * d0 - r0 * d2) / n
            w2 = (r0 * d1 - r1 * d0) / n
            i = ach_d[k]
            v[i] = m[0] * w0 + m[3] * w1 + m[6] * w2
            v[i + 1] = m[1] * w0 + m[4] * w1 + m[7] * w2
            v[i + 2] = m[2] * w0 + m[5] * w1 + m[8] * w2
        else:
            x0, x1, x2 = pla_axis[k - 2, 0], pla_axis[k - 2, 1], pla_axis[k - 2, 2]
            a0 = m[0] * x0 + m[1] * x1 + m[2] * x2
            a1 = m[3] * x0 + m[4] * x1 + m[5] * x2
            a2 = m[6] * x0 + m[7] * x1 + m[8] * x2
            n0 = a1 * r2 - a2 * r1
            n1 = a2 * r0 - a0 * r2
            n2 = a0 * r1 - a1 * r0
            v[pla_d[k - 2]] = (n0 * d0 + n1 * d1 + n2 * d2) / (n0 * n0 + n1 * n1 + n2 * n2)


# -- range check, sole points, foot speeds (processes/state_estimator/estimator.py) ---------
@_jit
def _in_bounds(x: np.ndarray, lo: np.ndarray, hi: np.ndarray, qn_lo: float,
               qn_hi: float) -> bool:
    """Every double within its bounds and the IMU quaternion (``x[0:4]``) of unit norm."""
    for i in range(x.size):
        if not (lo[i] <= x[i] <= hi[i]):
            return False
    n = x[0] * x[0] + x[1] * x[1] + x[2] * x[2] + x[3] * x[3]
    return qn_lo <= n <= qn_hi


@_jit
def _sole_points(foot_pos: np.ndarray, foot_axis: np.ndarray, up: np.ndarray,
                 r_imu: np.ndarray, radius: float, half: float, modes: np.ndarray,
                 h: np.ndarray, switched: np.ndarray) -> None:
    """Per foot: pick the bearing sole point (mid-sole, or heel/toe when pitched, with
    hysteresis), write it into ``h`` (IMU frame) and whether it changed into ``switched``."""
    for k in range(2):
        sp = (foot_axis[k, 0] * up[0] + foot_axis[k, 1] * up[1]
              + foot_axis[k, 2] * up[2])  # sine of the foot pitch
        mode = modes[k]
        if mode == 0 and abs(sp) > PITCH_ON:
            mode = -1 if sp > 0 else 1
        elif mode != 0 and (abs(sp) < PITCH_OFF or mode * sp > 0):
            mode = 0 if abs(sp) < PITCH_ON else (-1 if sp > 0 else 1)
        switched[k] = mode != modes[k]
        modes[k] = mode
        for i in range(3):
            h[k, i] = (foot_pos[k, i] - r_imu[i] - radius * up[i]
                       + mode * half * foot_axis[k, i])


@_jit
def _foot_speeds(R: np.ndarray, v_imu: np.ndarray, w: np.ndarray, foot_pos: np.ndarray,
                 foot_vel: np.ndarray, r_imu: np.ndarray, out: np.ndarray) -> None:
    """Each foot's speed in the world: v_imu + R (w x (p - r_imu) + v_rel), with p and v_rel
    the foot's position and velocity relative to the pelvis (pelvis frame, IMU aligned)."""
    for k in range(2):
        e0, e1, e2 = (foot_pos[k, 0] - r_imu[0], foot_pos[k, 1] - r_imu[1],
                      foot_pos[k, 2] - r_imu[2])
        b0 = w[1] * e2 - w[2] * e1 + foot_vel[k, 0]
        b1 = w[2] * e0 - w[0] * e2 + foot_vel[k, 1]
        b2 = w[0] * e1 - w[1] * e0 + foot_vel[k, 2]
        s = 0.0
        for i in range(3):
            vi = v_imu[i] + R[i, 0] * b0 + R[i, 1] * b1 + R[i, 2] * b2
            s += vi * vi
        out[k] = math.sqrt(s)


# == the fused per-packet step ===============================================================
# -- calling MuJoCo's C functions from compiled code -----------------------------------------
@intrinsic
def _call2(typingctx, fn, a, b):  # type: ignore[no-untyped-def]
    """``fn(a, b)`` for a C function ``void fn(void *, void *)`` at address ``fn`` (int64
    addresses: cacheable, unlike a ctypes function object, whose address is baked in)."""
    sig = types.void(types.int64, types.int64, types.int64)

    def codegen(context, builder, signature, args):  # type: ignore[no-untyped-def]
        f, x, y = args
        vp = ir.IntType(8).as_pointer()
        fnty = ir.FunctionType(ir.VoidType(), [vp, vp])
        builder.call(builder.inttoptr(f, fnty.as_pointer()),
                     [builder.inttoptr(x, vp), builder.inttoptr(y, vp)])
        return context.get_dummy_value()

    return sig, codegen


@intrinsic
def _f8_ptr(typingctx, addr):  # type: ignore[no-untyped-def]
    """The float64 pointer at address ``addr`` (for ``numba.carray`` over MjData's arrays)."""
    sig = types.CPointer(types.float64)(types.int64)

    def codegen(context, builder, signature, args):  # type: ignore[no-untyped-def]
        return builder.inttoptr(args[0], context.get_value_type(types.CPointer(types.float64)))

    return sig, codegen


#: the MuJoCo functions ``run`` calls, all ``void f(const mjModel*, mjData*)`` but the last,
#: ``void mju_mat2Quat(mjtNum quat[4], const mjtNum mat[9])``
MJ_FUNCTIONS = ("mj_kinematics", "mj_comPos", "mj_comVel", "mj_subtreeVel", "mju_mat2Quat")


def mujoco_functions() -> list[int]:
    """Addresses of ``MJ_FUNCTIONS`` in the libmujoco the ``mujoco`` package has loaded."""
    libs = sorted(glob.glob(os.path.join(os.path.dirname(mujoco.__file__), "libmujoco.so*")))
    if not libs:
        raise RuntimeError("the mujoco package's libmujoco.so was not found next to it: the "
                           "fused estimator step calls MuJoCo's C functions directly")
    try:  # the copy already loaded by the bindings (RTLD_NOLOAD), never a second one
        lib = ctypes.CDLL(libs[-1], mode=os.RTLD_NOLOAD | os.RTLD_LAZY)
    except OSError:
        lib = ctypes.CDLL(libs[-1])
    return [int(ctypes.cast(getattr(lib, name), ctypes.c_void_p).value or 0)
            for name in MJ_FUNCTIONS]


# -- the packed buffers -----------------------------------------------------------------------
def _offsets(spec: tuple[tuple[str, int], ...]) -> tuple[dict[str, int], int]:
    out, o = {}, 0
    for name, n in spec:
        out[name] = o
        o += n
    return out, o


#: ``W`` (uint8, 480): the datagram at byte 4, so that its doubles (from byte 12 of the packet)
#: are 8-byte aligned: as float64, packet byte ``b`` is element ``(b + 4) // 8``
W_SIZE = OUTPUT_SIZE + 4
_PKT = {name: (OUTPUT_LAYOUT.fields[name][1] + 4) // 8 for name in (
    "imu_quat", "imu_gyro", "imu_accel", "motor_pos", "motor_vel", "motor_torque", "joint_pos",
    "joint_vel", "task_time_s")}
W_QUAT, W_GYRO, W_ACCEL = _PKT["imu_quat"], _PKT["imu_gyro"], _PKT["imu_accel"]
W_MPOS, W_MVEL, W_MTAU = _PKT["motor_pos"], _PKT["motor_vel"], _PKT["motor_torque"]
W_JPOS, W_JVEL = _PKT["joint_pos"], _PKT["joint_vel"]
W_UTIME = (OUTPUT_LAYOUT.fields["utime"][1] + 4) // 8  # as int64
W_VERSION = OUTPUT_LAYOUT.fields["version"][1] + 4  # as uint8
W_KIND = OUTPUT_LAYOUT.fields["kind"][1] + 4
W_STATUS = (OUTPUT_LAYOUT.fields["status"][1] + 4) // 4  # as uint32
#: the doubles the range check bounds (imu_quat .. joint_vel) and those checked finite (all)
W_NCHECK = _PKT["task_time_s"] - W_QUAT
W_NFINITE = W_NCHECK + 1
if (any((OUTPUT_LAYOUT.fields[f][1] + 4) % 8 for f in _PKT)
        or OUTPUT_LAYOUT.fields["utime"][1] + 8 != OUTPUT_LAYOUT.fields["imu_quat"][1]
        or OUTPUT_LAYOUT.fields["task_time_s"][1] + 8 != OUTPUT_LAYOUT.fields["overruns"][1]
        or [f for f in OUTPUT_LAYOUT.names if OUTPUT_LAYOUT[f].base.kind == "f"] != list(_PKT)
        or sum(OUTPUT_LAYOUT[f].itemsize for f in list(_PKT)[:-1]) != 8 * W_NCHECK
        or (OUTPUT_LAYOUT.fields["status"][1] + 4) % 4):
    raise ImportError("runtime.cassie_packets layout changed: update the fused estimator step")

#: ``S`` (float64): the estimator's state and outputs. Fixed-size slots at constant offsets;
#: the model-sized vectors (``S_DYNAMIC``) follow, at offsets kept in ``CI``
_S_SPEC = (
    ("R", 9), ("V", 3), ("P", 3), ("D", 6), ("COV", DIM * DIM), ("SCRATCH", 9),  # InEKF
    ("GYRO_PREV", 3), ("H", 6), ("FOOT_SPEED", 2), ("QUAT", 4), ("VB", 3),  # estimator
    ("FOOT_POS", 6), ("FOOT_AXIS", 6), ("FOOT_VEL", 6), ("SPRING", 4),  # kinematics
    ("COM_B", 3), ("COMVEL_B", 3), ("ANGMOM_B", 3),
    ("FORCE", 2),  # contact
    ("EST_FORCE", 2), ("EST_SPRING", 2), ("ALIP_X", 4), ("ALIP_RAW", 4), ("STANCE_POS", 3),
    ("EST_COM", 3), ("EST_COMVEL", 3),  # the Estimate
    ("KF_X", 4), ("KF_P", 16), ("KF_F", 16), ("KF_Q", 16), ("KF_R", 16), ("KF_DT", 1),
    ("ALIP_DT", 1),  # the ALIP Kalman filter (fused step only) and a pending step's dt
)
S_OFF, S_FIXED = _offsets(_S_SPEC)
(S_R, S_V, S_P, S_D, S_COV, S_SCRATCH, S_GYRO_PREV, S_H, S_FOOT_SPEED, S_QUAT, S_VB,
 S_FOOT_POS, S_FOOT_AXIS, S_FOOT_VEL, S_SPRING, S_COM_B, S_COMVEL_B, S_ANGMOM_B, S_FORCE,
 S_EST_FORCE, S_EST_SPRING, S_ALIP_X, S_ALIP_RAW, S_STANCE_POS, S_EST_COM, S_EST_COMVEL,
 S_KF_X, S_KF_P, S_KF_F, S_KF_Q, S_KF_R, S_KF_DT, S_ALIP_DT) = (S_OFF[n] for n, _ in _S_SPEC)
#: after the fixed slots, in this order: kinematics q (nq) and v (nv), then the message block
#: of the Estimate's q (nq) and v (nv), the packet's motor torques and IMU specific force
S_DYNAMIC = ("KQ", "KV", "EQ", "EV", "TORQUE", "ACCEL")

#: ``I`` (int64): integer state. The first ``I_OUT`` entries are what the process publishes
_I_SPEC = (
    ("UTIME", 1), ("STATUS", 1), ("EST_STANCE", 1), ("FC", 2), ("DIRTY", 1),
    ("TARGET_STATUS", 1),  # out: utime, status, alip stance, in contact, ALIP fields changed
    ("INIT", 1), ("UPDATES", 1), ("STALE", 1), ("LAST_UTIME", 1), ("ALIP_UTIME", 1),
    ("STEPS", 1), ("CC", 2), ("MODE", 2), ("ALIP_STANCE", 1), ("PEND_STANCE", 1),
    ("STILL_SINCE", 1),  # utime the IMU has read at rest since, with no foot down (-1: not)
)
I_OFF, I_SIZE = _offsets(_I_SPEC)
(I_UTIME, I_STATUS, I_EST_STANCE, I_FC, I_DIRTY, I_TARGET_STATUS, I_INIT, I_UPDATES, I_STALE,
 I_LAST_UTIME, I_ALIP_UTIME, I_STEPS, I_CC, I_MODE, I_ALIP_STANCE,
 I_PEND_STANCE, I_STILL_SINCE) = (I_OFF[n] for n, _ in _I_SPEC)
I_OUT = I_TARGET_STATUS + 1

#: ``C`` (float64): constants
_C_SPEC = (
    ("PROTO", 2),  # the packet's version and kind bytes (data, not compiled in: see _checks)
    ("LO", W_NCHECK), ("HI", W_NCHECK), ("QN_LO", 1), ("QN_HI", 1),  # range check
    ("R_IMU", 3), ("G", 3), ("VAR_G", 1), ("VAR_A", 1), ("VAR_C", 1), ("VAR_S", 1),
    ("KIN_VAR", 1),  # InEKF
    ("STILL_GYRO", 1), ("STILL_ACCEL", 1), ("STILL_AFTER_US", 1), ("STILL_VAR", 1),  # at rest
    ("GAIN", 2), ("ON_N", 1), ("OFF_N", 1), ("TD_SPEED", 1),  # contact
    ("FOOT_RADIUS", 1), ("FOOT_HALF", 1), ("MASS", 1),
    ("TGT_OFF", 12), ("ACH_DIR", 6), ("PLA_AXIS", 6), ("PLA_TIP_PROJ", 6), ("ROD_TIP", 12),
    ("FOOT_LOCAL", 12), ("SPRING_REF", 4),  # kinematics
)
C_OFF, C_SIZE = _offsets(_C_SPEC)
(C_PROTO, C_LO, C_HI, C_QN_LO, C_QN_HI, C_R_IMU, C_G, C_VAR_G, C_VAR_A, C_VAR_C, C_VAR_S, C_KIN_VAR,
 C_STILL_GYRO, C_STILL_ACCEL, C_STILL_AFTER_US, C_STILL_VAR, C_GAIN, C_ON_N, C_OFF_N,
 C_TD_SPEED, C_FOOT_RADIUS, C_FOOT_HALF, C_MASS, C_TGT_OFF,
 C_ACH_DIR, C_PLA_AXIS, C_PLA_TIP_PROJ, C_ROD_TIP, C_FOOT_LOCAL,
 C_SPRING_REF) = (C_OFF[n] for n, _ in _C_SPEC)

#: ``CI`` (int64): index tables, sizes, the dynamic offsets of ``S``, addresses
_CI_SPEC = (
    ("MOTOR_QPOS", NUM_MOTORS), ("MOTOR_DOF", NUM_MOTORS), ("JOINT_QPOS", NUM_JOINTS),
    ("JOINT_DOF", NUM_JOINTS), ("ACH_QPOS", 2), ("PLA_QPOS", 2), ("ACH_DOF", 2), ("PLA_DOF", 2),
    ("ROD_BODY", 4), ("TGT_BODY", 4), ("FOOT_BODY", 2), ("SPRING_QPOS", 4), ("PELVIS", 1),
    ("NQ", 1), ("NV", 1), ("NBODY", 1),
    ("KQ", 1), ("KV", 1), ("EQ", 1), ("EV", 1), ("TORQUE", 1), ("ACCEL", 1),  # S offsets
    ("FN", len(MJ_FUNCTIONS)), ("MODEL", 1), ("DATA", 1),  # C entry points, mjModel*, mjData*
    ("QPOS", 1), ("QVEL", 1), ("XPOS", 1), ("XMAT", 1), ("CVEL", 1), ("SUBTREE_COM", 1),
    ("SUBTREE_LINVEL", 1), ("SUBTREE_ANGMOM", 1),  # addresses of MjData's arrays
)
CI_OFF, CI_SIZE = _offsets(_CI_SPEC)
(CI_MOTOR_QPOS, CI_MOTOR_DOF, CI_JOINT_QPOS, CI_JOINT_DOF, CI_ACH_QPOS, CI_PLA_QPOS,
 CI_ACH_DOF, CI_PLA_DOF, CI_ROD_BODY, CI_TGT_BODY, CI_FOOT_BODY, CI_SPRING_QPOS, CI_PELVIS,
 CI_NQ, CI_NV, CI_NBODY, CI_KQ, CI_KV, CI_EQ, CI_EV, CI_TORQUE, CI_ACCEL, CI_FN, CI_MODEL,
 CI_DATA, CI_QPOS, CI_QVEL, CI_XPOS, CI_XMAT, CI_CVEL, CI_SUBTREE_COM, CI_SUBTREE_LINVEL,
 CI_SUBTREE_ANGMOM) = (CI_OFF[n] for n, _ in _CI_SPEC)
FN_KINEMATICS, FN_COMPOS, FN_COMVEL, FN_SUBTREEVEL, FN_MAT2QUAT = range(CI_FN, CI_FN + 5)

# -- what ``run`` returns ---------------------------------------------------------------------
OK = 0
#: the datagram is not a valid robot-output packet / out of range / its time does not advance
#: (the caller asks ``OutputPacket.decode`` and ``CassieEstimator.check`` why, or what to do)
E_DECODE, E_RANGE, E_STALE = -1, -2, -3
E_NONFINITE = -4  # the estimate is not finite
#: the step stopped for Python to do something rare, then resumes at a later phase: the first
#: packet (or a restart) initialises the filter / every 1000th propagation re-orthonormalises R
#: (numpy's SVD) / the ALIP step has a new dt (scipy's expm)
NEED_INIT, NEED_SVD, NEED_ALIP_F = 1, 2, 3
#: phases: checks, kinematics, propagation, contact + correction + outputs, ALIP filter
PH_CHECK, PH_KIN, PH_PROPAGATE, PH_ESTIMATE, PH_ALIP = range(5)

STATUS_INITIALIZING = 1 << 0
STATUS_NO_CONTACT = 1 << 1
STATUS_PACKET_GAP = 1 << 2
STATUS_STILL = 1 << 3  # held still with no foot down: zero-velocity updates (_correct_still)


@_jit
def _checks(W: np.ndarray, PB: np.ndarray, S: np.ndarray, N: np.ndarray,
            C: np.ndarray) -> int:
    """``OutputPacket.decode`` (version, kind, finite doubles; then copied into the packet
    ``PB``) and ``CassieEstimator.check`` (bounds, IMU quaternion norm, time advancing)."""
    # (the version and kind come in C: numba's cache keeps a compiled global as it was when
    # this file last changed, and a new PROTOCOL_VERSION in cassie_packets would not reach it)
    if W[W_VERSION] != C[C_PROTO] or W[W_KIND] != C[C_PROTO + 1]:
        return E_DECODE
    wf = W.view(np.float64)
    for i in range(W_QUAT, W_QUAT + W_NFINITE):
        if not math.isfinite(wf[i]):
            return E_DECODE
    PB[:] = W[4:]
    if not _in_bounds(wf[W_QUAT:W_QUAT + W_NCHECK], C[C_LO:C_LO + W_NCHECK],
                      C[C_HI:C_HI + W_NCHECK], C[C_QN_LO], C[C_QN_HI]):
        return E_RANGE
    N[I_TARGET_STATUS] = W.view(np.uint32)[W_STATUS]
    if N[I_INIT] != 0 and W.view(np.int64)[W_UTIME] <= N[I_LAST_UTIME]:
        return E_STALE
    N[I_STALE] = 0
    return OK


@_jit
def _kinematics(wf: np.ndarray, S: np.ndarray, C: np.ndarray, CI: np.ndarray) -> None:
    """``LegKinematics.update``: the same kernels and MuJoCo calls, in the same order."""
    nq, nv, nb = CI[CI_NQ], CI[CI_NV], CI[CI_NBODY]
    m, d = CI[CI_MODEL], CI[CI_DATA]
    qpos = numba.carray(_f8_ptr(CI[CI_QPOS]), (nq,))
    qvel = numba.carray(_f8_ptr(CI[CI_QVEL]), (nv,))
    xpos = numba.carray(_f8_ptr(CI[CI_XPOS]), (nb, 3))
    xmat = numba.carray(_f8_ptr(CI[CI_XMAT]), (nb, 9))
    cvel = numba.carray(_f8_ptr(CI[CI_CVEL]), (nb, 6))
    scom = numba.carray(_f8_ptr(CI[CI_SUBTREE_COM]), (nb, 3))
    q = S[CI[CI_KQ]:CI[CI_KQ] + nq]
    v = S[CI[CI_KV]:CI[CI_KV] + nv]
    ach_q = CI[CI_ACH_QPOS:CI_ACH_QPOS + 2]
    pla_q = CI[CI_PLA_QPOS:CI_PLA_QPOS + 2]
    rod_body = CI[CI_ROD_BODY:CI_ROD_BODY + 4]
    tgt_body = CI[CI_TGT_BODY:CI_TGT_BODY + 4]
    foot_body = CI[CI_FOOT_BODY:CI_FOOT_BODY + 2]
    tgt_off = C[C_TGT_OFF:C_TGT_OFF + 12].reshape((4, 3))
    pla_axis = C[C_PLA_AXIS:C_PLA_AXIS + 6].reshape((2, 3))
    foot_pos = S[S_FOOT_POS:S_FOOT_POS + 6].reshape((2, 3))
    pelvis = CI[CI_PELVIS]
    _assemble(q, v, wf[W_MPOS:W_MPOS + NUM_MOTORS], wf[W_MVEL:W_MVEL + NUM_MOTORS],
              wf[W_JPOS:W_JPOS + NUM_JOINTS], wf[W_JVEL:W_JVEL + NUM_JOINTS],
              CI[CI_MOTOR_QPOS:CI_MOTOR_QPOS + NUM_MOTORS],
              CI[CI_MOTOR_DOF:CI_MOTOR_DOF + NUM_MOTORS],
              CI[CI_JOINT_QPOS:CI_JOINT_QPOS + NUM_JOINTS],
              CI[CI_JOINT_DOF:CI_JOINT_DOF + NUM_JOINTS], ach_q, pla_q, qpos)
    _call2(CI[FN_KINEMATICS], m, d)  # pass 1: rods at their zero angle
    _solve_rods(xpos, xmat, q, qpos, rod_body, tgt_body, tgt_off,
                C[C_ACH_DIR:C_ACH_DIR + 6].reshape((2, 3)), pla_axis,
                C[C_PLA_TIP_PROJ:C_PLA_TIP_PROJ + 6].reshape((2, 3)), ach_q, pla_q)
    _call2(CI[FN_KINEMATICS], m, d)
    _call2(CI[FN_COMPOS], m, d)
    _feet_and_springs(xpos, xmat, foot_body, C[C_FOOT_LOCAL:C_FOOT_LOCAL + 12].reshape((2, 3, 2)),
                      foot_pos, S[S_FOOT_AXIS:S_FOOT_AXIS + 6].reshape((2, 3)), q,
                      CI[CI_SPRING_QPOS:CI_SPRING_QPOS + 4].reshape((2, 2)),
                      C[C_SPRING_REF:C_SPRING_REF + 4].reshape((2, 2)),
                      S[S_SPRING:S_SPRING + 4].reshape((2, 2)))
    qvel[:] = v
    _call2(CI[FN_COMVEL], m, d)
    _foot_velocities(cvel, scom, pelvis, foot_body, foot_pos,
                     S[S_FOOT_VEL:S_FOOT_VEL + 6].reshape((2, 3)))
    _rod_velocities(xpos, xmat, cvel, scom, v, pelvis, rod_body, tgt_body,
                    C[C_ROD_TIP:C_ROD_TIP + 12].reshape((4, 3)), tgt_off, pla_axis,
                    CI[CI_ACH_DOF:CI_ACH_DOF + 2], CI[CI_PLA_DOF:CI_PLA_DOF + 2])


@_jit
def _still(N: np.ndarray, C: np.ndarray, utime: int, contact: bool, gyro: np.ndarray,
           accel: np.ndarray) -> bool:
    """Whether the robot has been at rest with no foot down for ``C_STILL_AFTER_US``: the
    zero-velocity update applies (``_correct_still``). Keeps ``I_STILL_SINCE``."""
    if contact or not _imu_at_rest(gyro, accel, -C[C_G + 2], C[C_STILL_GYRO],
                                   C[C_STILL_ACCEL]):
        N[I_STILL_SINCE] = -1
        return False
    if N[I_STILL_SINCE] < 0:
        N[I_STILL_SINCE] = utime
    return utime - N[I_STILL_SINCE] >= C[C_STILL_AFTER_US]


@_jit
def _estimate(wf: np.ndarray, S: np.ndarray, N: np.ndarray, C: np.ndarray, CI: np.ndarray,
              gap: bool) -> None:
    """``CassieEstimator.update`` after the propagation, up to the ALIP part: sole points,
    foot speeds, spring contact, touchdowns and lift-offs, the InEKF correction, and
    ``_fill``'s ``q``, ``v`` and status (the same arithmetic, in the same order)."""
    R = S[S_R:S_R + 9].reshape((3, 3))
    fv = S[S_V:S_V + 3]
    fp = S[S_P:S_P + 3]
    d = S[S_D:S_D + 6].reshape((2, 3))
    P = S[S_COV:S_COV + DIM * DIM].reshape((DIM, DIM))
    gyro = wf[W_GYRO:W_GYRO + 3]
    S[S_GYRO_PREV:S_GYRO_PREV + 3] = gyro
    N[I_LAST_UTIME] = _utime(wf)
    foot_pos = S[S_FOOT_POS:S_FOOT_POS + 6].reshape((2, 3))
    h = S[S_H:S_H + 6].reshape((2, 3))
    r_imu = C[C_R_IMU:C_R_IMU + 3]
    switched = np.zeros(2, dtype=np.bool_)
    _sole_points(foot_pos, S[S_FOOT_AXIS:S_FOOT_AXIS + 6].reshape((2, 3)), R[2], r_imu,
                 C[C_FOOT_RADIUS], C[C_FOOT_HALF], N[I_MODE:I_MODE + 2], h, switched)
    speed = S[S_FOOT_SPEED:S_FOOT_SPEED + 2]
    _foot_speeds(R, fv, gyro, foot_pos, S[S_FOOT_VEL:S_FOOT_VEL + 6].reshape((2, 3)), r_imu,
                 speed)
    # SpringContact.update: F = -(spring_defl @ gain), hysteresis, a start only on a slow foot
    sd = S[S_SPRING:S_SPRING + 4].reshape((2, 2))
    force = S[S_FORCE:S_FORCE + 2]
    g0, g1 = C[C_GAIN], C[C_GAIN + 1]
    for k in range(2):
        force[k] = -(sd[k, 0] * g0 + sd[k, 1] * g1)
        if N[I_CC + k] != 0:
            if force[k] < C[C_OFF_N]:
                N[I_CC + k] = 0
        elif force[k] > C[C_ON_N] and speed[k] < C[C_TD_SPEED]:
            N[I_CC + k] = 1
    # a new contact point (re)seeds its slot (ContactInEKF.touchdown); a lift-off frees it
    kv = C[C_KIN_VAR]
    for k in range(2):
        if N[I_CC + k] != 0 and (N[I_FC + k] == 0 or switched[k]):
            for i in range(3):
                d[k, i] = fp[i] + (R[i, 0] * h[k, 0] + R[i, 1] * h[k, 1] + R[i, 2] * h[k, 2])
            f = 9 + 3 * k
            for i in range(3):
                for j in range(DIM):
                    P[f + i, j] = P[6 + i, j]
            for j in range(DIM):
                for i in range(3):
                    P[j, f + i] = P[j, 6 + i]
            for i in range(3):
                for j in range(3):
                    P[f + i, f + j] = P[6 + i, 6 + j] + (kv if i == j else 0.0)
            N[I_FC + k] = 1
        elif N[I_CC + k] == 0 and N[I_FC + k] != 0:
            N[I_FC + k] = 0
    k0, k1 = N[I_FC] != 0, N[I_FC + 1] != 0
    if k0 or k1:
        _correct(R, fv, fp, d, P, h, k0, k1, kv)
    still = _still(N, C, _utime(wf), k0 or k1, gyro, wf[W_ACCEL:W_ACCEL + 3])
    if still:
        _correct_still(R, fv, fp, d, P, C[C_STILL_VAR])
    # _fill: pelvis origin from the IMU point: p - R r, v - R (w x r)
    nq, nv = CI[CI_NQ], CI[CI_NV]
    q = S[CI[CI_EQ]:CI[CI_EQ] + nq]
    v = S[CI[CI_EV]:CI[CI_EV] + nv]
    kq = S[CI[CI_KQ]:CI[CI_KQ] + nq]
    kvel = S[CI[CI_KV]:CI[CI_KV] + nv]
    q[7:] = kq[7:]
    v[6:] = kvel[6:]
    r00, r01, r02 = R[0, 0], R[0, 1], R[0, 2]
    r10, r11, r12 = R[1, 0], R[1, 1], R[1, 2]
    r20, r21, r22 = R[2, 0], R[2, 1], R[2, 2]
    w0, w1, w2 = gyro[0], gyro[1], gyro[2]
    x, y, z = r_imu[0], r_imu[1], r_imu[2]
    q[0] = fp[0] - (r00 * x + r01 * y + r02 * z)
    q[1] = fp[1] - (r10 * x + r11 * y + r12 * z)
    q[2] = fp[2] - (r20 * x + r21 * y + r22 * z)
    c0, c1, c2 = w1 * z - w2 * y, w2 * x - w0 * z, w0 * y - w1 * x
    vx, vy, vz = fv[0], fv[1], fv[2]
    vx -= r00 * c0 + r01 * c1 + r02 * c2
    vy -= r10 * c0 + r11 * c1 + r12 * c2
    vz -= r20 * c0 + r21 * c1 + r22 * c2
    v[0], v[1], v[2] = vx, vy, vz
    base = S.ctypes.data
    _call2(CI[FN_MAT2QUAT], base + 8 * S_QUAT, base + 8 * S_R)
    q[3:7] = S[S_QUAT:S_QUAT + 4]
    v[3:6] = gyro
    N[I_UTIME] = _utime(wf)
    S[S_EST_FORCE:S_EST_FORCE + 2] = force
    S[S_EST_SPRING] = sd[0, 0]
    S[S_EST_SPRING + 1] = sd[1, 0]
    status = 0
    if N[I_UPDATES] < 200:
        status |= STATUS_INITIALIZING
    if not (k0 or k1):
        status |= STATUS_NO_CONTACT
    if gap:
        status |= STATUS_PACKET_GAP
    if still:
        status |= STATUS_STILL
    N[I_STATUS] = status
    N[I_UPDATES] += 1
    # the message block: the packet's torques and specific force beside q and v
    S[CI[CI_TORQUE]:CI[CI_TORQUE] + NUM_MOTORS] = wf[W_MTAU:W_MTAU + NUM_MOTORS]
    S[CI[CI_ACCEL]:CI[CI_ACCEL] + 3] = wf[W_ACCEL:W_ACCEL + 3]


@_jit
def _utime(wf: np.ndarray) -> int:
    """The packet's ``utime`` (int64 at float64 element ``W_UTIME`` of the work buffer)."""
    return wf.view(np.int64)[W_UTIME]


@_jit
def _alip_measure(wf: np.ndarray, S: np.ndarray, N: np.ndarray, C: np.ndarray,
                  CI: np.ndarray) -> int:
    """``_fill``'s ALIP part up to the filter: CoM, momentum, stance, the raw ALIP state.
    Returns the stance foot (-1: none, nothing more to do)."""
    R = S[S_R:S_R + 9].reshape((3, 3))
    r00, r01, r02 = R[0, 0], R[0, 1], R[0, 2]
    r10, r11, r12 = R[1, 0], R[1, 1], R[1, 2]
    r20, r21, r22 = R[2, 0], R[2, 1], R[2, 2]
    nq, nv, nb = CI[CI_NQ], CI[CI_NV], CI[CI_NBODY]
    q = S[CI[CI_EQ]:CI[CI_EQ] + nq]
    v = S[CI[CI_EV]:CI[CI_EV] + nv]
    vx, vy, vz = v[0], v[1], v[2]
    vb = S[S_VB:S_VB + 3]  # pelvis velocity in the pelvis frame, R^T v
    vb[0] = r00 * vx + r10 * vy + r20 * vz
    vb[1] = r01 * vx + r11 * vy + r21 * vz
    vb[2] = r02 * vx + r12 * vy + r22 * vz
    # LegKinematics.update_momentum
    kv = S[CI[CI_KV]:CI[CI_KV] + nv]
    kv[0:3] = vb
    kv[3:6] = wf[W_GYRO:W_GYRO + 3]
    qvel = numba.carray(_f8_ptr(CI[CI_QVEL]), (nv,))
    qvel[:] = kv
    _call2(CI[FN_COMVEL], CI[CI_MODEL], CI[CI_DATA])
    _call2(CI[FN_SUBTREEVEL], CI[CI_MODEL], CI[CI_DATA])
    b = CI[CI_PELVIS]
    scom = numba.carray(_f8_ptr(CI[CI_SUBTREE_COM]), (nb, 3))
    slin = numba.carray(_f8_ptr(CI[CI_SUBTREE_LINVEL]), (nb, 3))
    sang = numba.carray(_f8_ptr(CI[CI_SUBTREE_ANGMOM]), (nb, 3))
    S[S_COM_B:S_COM_B + 3] = scom[b]
    S[S_COMVEL_B:S_COMVEL_B + 3] = slin[b]
    S[S_ANGMOM_B:S_ANGMOM_B + 3] = sang[b]
    bx, by, bz = scom[b, 0], scom[b, 1], scom[b, 2]
    ux, uy, uz = slin[b, 0], slin[b, 1], slin[b, 2]
    lx, ly, lz = sang[b, 0], sang[b, 1], sang[b, 2]
    cx = q[0] + r00 * bx + r01 * by + r02 * bz
    cy = q[1] + r10 * bx + r11 * by + r12 * bz
    cz = q[2] + r20 * bx + r21 * by + r22 * bz
    gx = r00 * ux + r01 * uy + r02 * uz
    gy = r10 * ux + r11 * uy + r12 * uz
    gz = r20 * ux + r21 * uy + r22 * uz
    S[S_EST_COM], S[S_EST_COM + 1], S[S_EST_COM + 2] = cx, cy, cz
    S[S_EST_COMVEL], S[S_EST_COMVEL + 1], S[S_EST_COMVEL + 2] = gx, gy, gz
    k0, k1 = N[I_FC] != 0, N[I_FC + 1] != 0
    stance = N[I_EST_STANCE]
    if k0 != k1:
        stance = 0 if k0 else 1
    elif k0 and stance < 0:
        stance = 0  # double stance from the start: the left foot, by convention
    N[I_DIRTY] = 1
    if stance < 0:
        N[I_EST_STANCE] = -1
        return -1
    d = S[S_D:S_D + 6].reshape((2, 3))
    sx, sy, sz = d[stance, 0], d[stance, 1], d[stance, 2]  # the stance foot's contact point
    S[S_STANCE_POS], S[S_STANCE_POS + 1], S[S_STANCE_POS + 2] = sx, sy, sz
    ex, ey, ez = cx - sx, cy - sy, cz - sz
    m = C[C_MASS]
    # L_p = L_com + m (c - p) x v_com (angular momentum transfer), world axes
    raw = S[S_ALIP_RAW:S_ALIP_RAW + 4]
    raw[0], raw[1] = ex, ey
    raw[2] = r00 * lx + r01 * ly + r02 * lz + m * (ey * gz - ez * gy)
    raw[3] = r10 * lx + r11 * ly + r12 * lz + m * (ez * gx - ex * gz)
    utime = _utime(wf)
    S[S_ALIP_DT] = (utime - N[I_ALIP_UTIME]) * 1e-6 if N[I_EST_STANCE] == stance else 0.0
    N[I_ALIP_UTIME] = utime
    return stance


@_fjit
def _mat4(a: np.ndarray, b: np.ndarray, out: np.ndarray, bt: bool) -> None:
    """out = a @ b (or a @ b^T), 4 x 4."""
    for i in range(4):
        for j in range(4):
            acc = 0.0
            for k in range(4):
                acc += a[i, k] * (b[j, k] if bt else b[k, j])
            out[i, j] = acc


@_fjit
def _alip_filter(S: np.ndarray, N: np.ndarray, stance: int) -> bool:
    """``AlipKalman.step`` (filterpy's predict and update with ``H = I``, in filterpy's
    order; the inverse by LU with partial pivoting, as LAPACK's): False when the step needs
    the model discretised for its dt first (``NEED_ALIP_F``). A singular innovation matrix
    (filterpy: ``LinAlgError``) gives a non-finite state, which the caller drops."""
    z = S[S_ALIP_RAW:S_ALIP_RAW + 4]
    dt = S[S_ALIP_DT]
    x = S[S_KF_X:S_KF_X + 4]
    P = S[S_KF_P:S_KF_P + 16].reshape((4, 4))
    Rm = S[S_KF_R:S_KF_R + 16].reshape((4, 4))
    if stance != N[I_ALIP_STANCE] or dt <= 0.0 or dt > 0.05:
        # new stance foot (or a long gap): the state jumped, restart from the measurement
        N[I_ALIP_STANCE] = stance
        x[:] = z
        P[:, :] = Rm
    else:
        if not abs(dt - S[S_KF_DT]) < 1e-9:
            return False
        F = S[S_KF_F:S_KF_F + 16].reshape((4, 4))
        Q = S[S_KF_Q:S_KF_Q + 16].reshape((4, 4))
        # predict: x = F x; P = F P F^T + Q
        xn = np.empty(4)
        for i in range(4):
            acc = 0.0
            for k in range(4):
                acc += F[i, k] * x[k]
            xn[i] = acc
        x[:] = xn
        fp = np.empty((4, 4))
        _mat4(F, P, fp, False)
        _mat4(fp, F, P, True)
        for i in range(4):
            for j in range(4):
                P[i, j] = P[i, j] + Q[i, j]
        # update: y = z - x; S = P + R; K = P S^-1; x += K y; P = (I-K) P (I-K)^T + K R K^T
        y = np.empty(4)
        for i in range(4):
            y[i] = z[i] - x[i]
        sm = np.empty((4, 4))
        for i in range(4):
            for j in range(4):
                sm[i, j] = P[i, j] + Rm[i, j]
        si = _inv4(sm)
        K = np.empty((4, 4))
        _mat4(P, si, K, False)
        for i in range(4):
            acc = 0.0
            for k in range(4):
                acc += K[i, k] * y[k]
            x[i] = x[i] + acc
        ikh = np.empty((4, 4))
        for i in range(4):
            for j in range(4):
                ikh[i, j] = (1.0 if i == j else 0.0) - K[i, j]
        a = np.empty((4, 4))
        b = np.empty((4, 4))
        kr = np.empty((4, 4))
        _mat4(ikh, P, a, False)
        _mat4(a, ikh, b, True)
        _mat4(K, Rm, kr, False)
        _mat4(kr, K, a, True)
        for i in range(4):
            for j in range(4):
                P[i, j] = b[i, j] + a[i, j]
    S[S_ALIP_X:S_ALIP_X + 4] = x
    return True


@_fjit
def _inv4(a: np.ndarray) -> np.ndarray:
    """The inverse of a 4 x 4 matrix: LU with partial pivoting, then solves for I."""
    lu = a.copy()
    piv = np.arange(4)
    for c in range(4):
        p = c
        for r in range(c + 1, 4):
            if abs(lu[r, c]) > abs(lu[p, c]):
                p = r
        if p != c:
            for j in range(4):
                lu[c, j], lu[p, j] = lu[p, j], lu[c, j]
            piv[c], piv[p] = piv[p], piv[c]
        for r in range(c + 1, 4):
            lu[r, c] /= lu[c, c]
            for j in range(c + 1, 4):
                lu[r, j] -= lu[r, c] * lu[c, j]
    out = np.empty((4, 4))
    for col in range(4):
        y = np.empty(4)
        for i in range(4):  # L y = P e_col
            acc = 1.0 if piv[i] == col else 0.0
            for k in range(i):
                acc -= lu[i, k] * y[k]
            y[i] = acc
        for i in range(3, -1, -1):  # U x = y
            acc = y[i]
            for k in range(i + 1, 4):
                acc -= lu[i, k] * out[k, col]
            out[i, col] = acc / lu[i, i]
    return out


@_jit
def _finite(S: np.ndarray, CI: np.ndarray) -> bool:
    """The published estimate (``q``, ``v``, ALIP state) is finite."""
    e0 = CI[CI_EQ]
    for i in range(e0, e0 + CI[CI_NQ] + CI[CI_NV]):  # EQ and EV are adjacent
        if not math.isfinite(S[i]):
            return False
    for i in range(S_ALIP_X, S_ALIP_X + 4):  # noqa: SIM110  (a plain loop for numba)
        if not math.isfinite(S[i]):
            return False
    return True


@_jit
def run(phase: int, alip: bool, gap: bool, W: np.ndarray, PB: np.ndarray, S: np.ndarray,
        N: np.ndarray, C: np.ndarray, CI: np.ndarray) -> int:
    """One packet (in ``W``) from ``phase`` on: ``OK``, an ``E_*`` rejection, or a ``NEED_*``
    for the caller to serve before calling again at the phase that follows it.

    ``alip``: also the CoM, momentum and ALIP filter (the laptop's packets); ``gap``: packets
    were lost before this one (a status bit); ``PB``: the ``OutputPacket`` buffer the valid
    datagram is copied into."""
    wf = W.view(np.float64)
    if phase <= PH_CHECK:
        N[I_DIRTY] = 0
        code = _checks(W, PB, S, N, C)
        if code != OK:
            return code
    if phase <= PH_KIN:
        _kinematics(wf, S, C, CI)
        if N[I_INIT] == 0:
            return NEED_INIT
    if phase <= PH_PROPAGATE:
        # gyro of the previous sample (zero-order hold over the interval), accel of this one
        dt = (_utime(wf) - N[I_LAST_UTIME]) * 1e-6
        if dt > 0.0:
            c0, c1 = N[I_FC] != 0, N[I_FC + 1] != 0
            _propagate(S[S_R:S_R + 9].reshape((3, 3)), S[S_V:S_V + 3], S[S_P:S_P + 3],
                       S[S_D:S_D + 6].reshape((2, 3)),
                       S[S_COV:S_COV + DIM * DIM].reshape((DIM, DIM)),
                       S[S_GYRO_PREV:S_GYRO_PREV + 3], wf[W_ACCEL:W_ACCEL + 3], dt,
                       C[C_G:C_G + 3], C[C_VAR_G], C[C_VAR_A],
                       C[C_VAR_C] if c0 else C[C_VAR_S], C[C_VAR_C] if c1 else C[C_VAR_S],
                       S[S_SCRATCH:S_SCRATCH + 9].reshape((3, 3)))
            N[I_STEPS] += 1
            if N[I_STEPS] % 1000 == 0:  # keep R on SO(3) against round-off
                return NEED_SVD
    if phase <= PH_ESTIMATE:
        _estimate(wf, S, N, C, CI, gap)
        if alip:
            stance = _alip_measure(wf, S, N, C, CI)
            N[I_PEND_STANCE] = stance
            if stance >= 0 and not _alip_filter(S, N, stance):
                return NEED_ALIP_F
            if stance >= 0:
                N[I_EST_STANCE] = stance
    elif phase == PH_ALIP:
        stance = N[I_PEND_STANCE]
        if not _alip_filter(S, N, stance):
            return NEED_ALIP_F
        N[I_EST_STANCE] = stance
    return OK if _finite(S, CI) else E_NONFINITE
