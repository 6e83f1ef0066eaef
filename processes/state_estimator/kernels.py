"""Every compiled kernel of the state estimator, in one file.

numba caches each kernel on disk and revalidates the cache against the file the kernel is
defined in, not the files of the kernels it calls: a kernel that calls others (as a fused
per-packet step will call all of them) must live in the same file as they do, or a change to
one of them would leave a stale compiled copy in the caller's cache.

The kernels are used by ``kinematics.LegKinematics``, ``inekf.ContactInEKF`` and
``estimator.CassieEstimator``; each works in place on preallocated arrays.
"""

from __future__ import annotations

import math

import numba
import numpy as np

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

