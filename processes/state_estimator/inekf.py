"""Contact-aided invariant EKF on SE_4(3) (Hartley, Ghaffari, Eustice, Grizzle, IJRR 2020).

State ``X = (R, v, p, d_left, d_right)``: IMU orientation (world <- IMU), IMU velocity and
position (world), and one world-frame contact point per foot, as the group element

    X = [[R, v, p, dL, dR], [0, 1, 0, 0, 0], ..., [0, 0, 0, 0, 1]]   (7 x 7)

with the *right-invariant* error ``eta = X_hat X^-1 ~ I + xi^``, ``xi = (phi, xi_v, xi_p,
xi_dL, xi_dR)`` (15). Because the IMU dynamics are group affine, the linearised error dynamics
do not depend on the estimate (Hartley Sec. 5, eq. (26)): ``A`` has ``[g]x`` in the (v, R)
block and ``I`` in the (p, v) block, and the process noise enters through ``Ad_X``. The leg
kinematics ``h = R^T (d - p)`` is a right-invariant observation ``Y = X^-1 b`` (Hartley
Sec. 6, eq. (36)-(40)), so its Jacobian ``H = [0, 0, -I, +I at d_k]`` is constant too.

The contact slots have a fixed size (no state augmentation at 2 kHz): a foot that is not in
contact keeps a stale point that is never used; at touchdown it is re-initialised to
``p + R h`` and its covariance copied from ``p`` (the right-invariant error of a new contact
point equals the error of ``p``, Hartley Sec. 6-C), plus the kinematics noise.

The IMU biases are not estimated: the MuJoCo target PC's IMU is bias-free (a real robot
needs the bias-augmented "imperfect IEKF" of Hartley Sec. 7).

The propagation and correction are compiled (numba, cached on disk) and work in place on the
preallocated state: at 2 kHz, numpy's per-call cost on 3- and 15-element arrays was most of
the filter's time (about 0.19 ms per packet, now about 0.01 ms).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

#: state slices (rows of the 15-dim error)
ROT, VEL, POS = slice(0, 3), slice(3, 6), slice(6, 9)
FOOT = (slice(9, 12), slice(12, 15))
DIM = 15


@dataclass(frozen=True)
class InEKFNoise:
    """Continuous-time noise densities (std devs) and initial uncertainty of the InEKF."""

    gyro: float = 0.002  # rad/s/sqrt(Hz)
    accel: float = 0.04  # m/s^2/sqrt(Hz)
    contact: float = 0.01  # m/s/sqrt(Hz): a planted foot's slip
    swing: float = 1.0  # m/s/sqrt(Hz): a foot that is not in contact
    kinematics: float = 0.005  # m: leg kinematics (encoders, spring model) per axis
    init_rot: float = 0.02  # rad
    init_vel: float = 0.1  # m/s
    init_pos: float = 0.01  # m


def skew(w: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """The 3x3 cross-product matrix [w]x."""
    s = np.zeros((3, 3)) if out is None else out
    s[0, 1], s[0, 2] = -w[2], w[1]
    s[1, 0], s[1, 2] = w[2], -w[0]
    s[2, 0], s[2, 1] = -w[1], w[0]
    return s


# -- compiled kernels (no numpy temporaries of the caller's arrays; all in place) ------------
_jit = numba.njit(cache=True, nogil=True, error_model="numpy")


@_jit
def _so3_coeffs(x: float, y: float, z: float) -> tuple[float, float, float]:
    """(sin t / t, (1 - cos t) / t^2, (t - sin t) / t^3) for t = |(x, y, z)|, series near 0."""
    th2 = x * x + y * y + z * z
    if th2 < 1e-12:
        return 1.0 - th2 / 6.0, 0.5 - th2 / 24.0, 1.0 / 6.0 - th2 / 120.0
    th = math.sqrt(th2)
    sn, co = math.sin(th), math.cos(th)
    return sn / th, (1.0 - co) / th2, (th - sn) / (th2 * th)


@_jit
def _i_plus(out: np.ndarray, a: float, b: float, x: float, y: float, z: float) -> None:
    """out = I + a [w]x + b [w]x^2 (Rodrigues-type series), w = (x, y, z)."""
    xx, yy, zz, xy, xz, yz = x * x, y * y, z * z, x * y, x * z, y * z
    out[0, 0], out[0, 1], out[0, 2] = 1.0 - b * (yy + zz), -a * z + b * xy, a * y + b * xz
    out[1, 0], out[1, 1], out[1, 2] = a * z + b * xy, 1.0 - b * (xx + zz), -a * x + b * yz
    out[2, 0], out[2, 1], out[2, 2] = -a * y + b * xz, a * x + b * yz, 1.0 - b * (xx + yy)


@_jit
def _skew_rows(n: np.ndarray, r0: int, w: np.ndarray) -> None:
    """Rows r0..r0+2 of ``n`` (.., 3) := [w]x."""
    x, y, z = w[0], w[1], w[2]
    n[r0, 0], n[r0, 1], n[r0, 2] = 0.0, -z, y
    n[r0 + 1, 0], n[r0 + 1, 1], n[r0 + 1, 2] = z, 0.0, -x
    n[r0 + 2, 0], n[r0 + 2, 1], n[r0 + 2, 2] = -y, x, 0.0


@_jit
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


@_jit
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


class ContactInEKF:
    """Right-invariant contact-aided InEKF with two fixed contact slots (left, right foot)."""

    def __init__(self, noise: InEKFNoise | None = None, gravity: float = 9.81) -> None:
        self.noise = n = noise or InEKFNoise()
        self.g = np.array((0.0, 0.0, -gravity))
        self.R = np.eye(3)
        self.v = np.zeros(3)
        self.p = np.zeros(3)
        self.d = np.zeros((2, 3))
        self.P = np.eye(DIM)
        self.contact = [False, False]
        self._var_g = n.gyro**2
        self._var_a = n.accel**2
        self._var_c = n.contact**2
        self._var_s = n.swing**2
        self._kin_var = n.kinematics**2
        self._scratch = np.zeros((3, 3))
        self._steps = 0
        self._warm_up()

    def _warm_up(self) -> None:
        """Compile (or load from the on-disk cache) both kernels now, not on the first packet."""
        R, v, p, d, P = np.eye(3), np.zeros(3), np.zeros(3), np.zeros((2, 3)), np.eye(DIM)
        _propagate(R, v, p, d, P, np.zeros(3), np.zeros(3), 5e-4, self.g, 1.0, 1.0, 1.0, 1.0,
                   self._scratch)
        _correct(R, v, p, d, P, np.zeros((2, 3)), True, False, 1e-4)

    # -- set-up -----------------------------------------------------------------------------
    def reset(self, R: np.ndarray, v: np.ndarray, p: np.ndarray) -> None:
        """Start from orientation ``R``, velocity ``v`` and position ``p`` (IMU, world)."""
        n = self.noise
        self.R[:] = R
        self.v[:] = v
        self.p[:] = p
        self.d[:] = p
        self.contact = [False, False]
        self.P[:] = 0.0
        diag = np.zeros(DIM)
        diag[ROT] = n.init_rot**2
        diag[VEL] = n.init_vel**2
        diag[POS] = n.init_pos**2
        diag[9:] = 1.0
        np.fill_diagonal(self.P, diag)

    # -- propagation (Hartley Sec. 5) -------------------------------------------------------
    def propagate(self, gyro: np.ndarray, accel: np.ndarray, dt: float) -> None:
        """IMU step: ``gyro`` (rad/s) and ``accel`` (specific force, m/s^2) in the IMU frame."""
        if dt <= 0.0:
            return
        _propagate(self.R, self.v, self.p, self.d, self.P, gyro, accel, dt, self.g,
                   self._var_g, self._var_a,
                   self._var_c if self.contact[0] else self._var_s,
                   self._var_c if self.contact[1] else self._var_s, self._scratch)
        self._steps += 1
        if self._steps % 1000 == 0:  # keep R on SO(3) against round-off
            u, _, vt = np.linalg.svd(self.R)
            self.R[:] = u @ vt

    # -- contacts (Hartley Sec. 6-C) ---------------------------------------------------------
    def touchdown(self, k: int, h: np.ndarray) -> None:
        """Foot ``k`` starts a contact at ``h`` (IMU frame): re-initialise its slot."""
        f = FOOT[k]
        self.d[k] = self.p + self.R @ h
        P = self.P
        P[f, :] = P[POS, :]
        P[:, f] = P[:, POS]
        P[f, f] = P[POS, POS] + self._kin_var * np.eye(3)
        self.contact[k] = True

    def liftoff(self, k: int) -> None:
        """Foot ``k`` left the ground: its slot is no longer measured."""
        self.contact[k] = False

    # -- correction (Hartley Sec. 6, eq. (36)-(40)) ------------------------------------------
    def correct(self, h: np.ndarray) -> None:
        """Leg-kinematics update with ``h`` (2, 3): each contact foot's point in the IMU frame.

        Innovation ``z_k = R h_k - (d_k - p)``; ``H_k = [0, 0, -I, +I at d_k]`` (constant: the
        right-invariant observation of Hartley eq. (40)); noise ``R N R^T = N`` for the
        isotropic kinematics noise ``N``.
        """
        c0, c1 = self.contact
        if c0 or c1:
            _correct(self.R, self.v, self.p, self.d, self.P, h, c0, c1, self._kin_var)
