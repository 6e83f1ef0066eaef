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
"""

from __future__ import annotations

import math
from dataclasses import dataclass

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


def _skew_into(s: np.ndarray, w: np.ndarray) -> None:
    """Write [w]x into the 3x3 view ``s`` (diagonal assumed zero already)."""
    x, y, z = w.tolist()
    s[0, 1], s[0, 2] = -z, y
    s[1, 0], s[1, 2] = z, -x
    s[2, 0], s[2, 1] = -y, x


def _so3_coeffs(x: float, y: float, z: float) -> tuple[float, float, float]:
    """(sin t / t, (1 - cos t) / t^2, (t - sin t) / t^3) for t = |(x, y, z)|, series near 0."""
    th2 = x * x + y * y + z * z
    if th2 < 1e-12:
        return 1.0 - th2 / 6.0, 0.5 - th2 / 24.0, 1.0 / 6.0 - th2 / 120.0
    th = math.sqrt(th2)
    sn, co = math.sin(th), math.cos(th)
    return sn / th, (1.0 - co) / th2, (th - sn) / (th2 * th)


def _i_plus(a: float, b: float, x: float, y: float, z: float) -> list[list[float]]:
    """I + a [w]x + b [w]x^2 as nested lists (Rodrigues-type series), w = (x, y, z)."""
    xx, yy, zz, xy, xz, yz = x * x, y * y, z * z, x * y, x * z, y * z
    return [
        [1.0 - b * (yy + zz), -a * z + b * xy, a * y + b * xz],
        [a * z + b * xy, 1.0 - b * (xx + zz), -a * x + b * yz],
        [-a * y + b * xz, a * x + b * yz, 1.0 - b * (xx + yy)],
    ]


def so3_exp(phi: np.ndarray) -> np.ndarray:
    """Rodrigues' formula: Exp(phi) in SO(3). Scalar Python: ~5x cheaper than numpy here."""
    x, y, z = phi.tolist()
    a, b, _ = _so3_coeffs(x, y, z)
    return np.array(_i_plus(a, b, x, y, z))


def so3_exp_and_jl(phi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Exp(phi) and the left Jacobian J_l(phi) = I + b [phi]x + c [phi]x^2 of SO(3)."""
    x, y, z = phi.tolist()
    a, b, c = _so3_coeffs(x, y, z)
    return np.array(_i_plus(a, b, x, y, z)), np.array(_i_plus(b, c, x, y, z))


class ContactInEKF:
    """Right-invariant contact-aided InEKF with two fixed contact slots (left, right foot)."""

    def __init__(self, noise: InEKFNoise | None = None, gravity: float = 9.81) -> None:
        self.noise = noise or InEKFNoise()
        self.g = np.array((0.0, 0.0, -gravity))
        self.R = np.eye(3)
        self.v = np.zeros(3)
        self.p = np.zeros(3)
        self.d = np.zeros((2, 3))
        self.P = np.eye(DIM)
        self.contact = [False, False]
        n = self.noise
        # A of the linearised error dynamics (Hartley eq. (26)); A^3 = 0, so
        # Phi = exp(A dt) = I + A dt + A^2 dt^2 / 2 exactly.
        self._g_skew = skew(self.g)
        self._phi = np.eye(DIM)
        self._phi_dt = -1.0
        self._N = np.zeros((DIM, 3))
        self._N[ROT] = np.eye(3)
        self._qhat = np.zeros((DIM, DIM))
        self._qdiag = np.zeros(DIM)
        self._qdiag[VEL] = n.accel**2
        self._di = np.diag_indices(DIM)
        self._var_g = n.gyro**2
        self._var_c = n.contact**2
        self._var_s = n.swing**2
        self._kin_var = n.kinematics**2
        self._r3 = np.zeros((3, 3))
        self._blocks = np.zeros((4, 3))
        # H for each contact set (Hartley eq. (40)), its transpose and the noise N
        self._H: dict[tuple[bool, bool], tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
        for key, feet in (((True, False), (0,)), ((False, True), (1,)), ((True, True), (0, 1))):
            H = np.zeros((3 * len(feet), DIM))
            for i, k in enumerate(feet):
                H[3 * i : 3 * i + 3, POS] = -np.eye(3)
                H[3 * i : 3 * i + 3, FOOT[k]] = np.eye(3)
            self._H[key] = (H, H.T.copy(), self._kin_var * np.eye(3 * len(feet)))
        self._tmp = np.zeros((DIM, DIM))
        self._steps = 0

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
        R = self.R
        a_world = R @ accel + self.g
        # process noise Ad_X Q Ad_X^T (Hartley eq. (27)) for isotropic Q blocks: the gyro part
        # is s_g^2 N N^T with N = [I; v^; p^; dL^; dR^] (the R R^T in between cancels), the
        # accelerometer and contact parts are s^2 I on their own blocks.
        nn = self._N
        _skew_into(nn[VEL], self.v)
        _skew_into(nn[POS], self.p)
        _skew_into(nn[FOOT[0]], self.d[0])
        _skew_into(nn[FOOT[1]], self.d[1])
        qd = self._qhat
        np.matmul(nn, nn.T, out=qd)
        qd *= self._var_g
        diag = self._qdiag
        diag[9:12] = self._var_c if self.contact[0] else self._var_s
        diag[12:15] = self._var_c if self.contact[1] else self._var_s
        qd[self._di] += diag
        # mean: R+ = R Exp(w dt), v+ = v + a dt, p+ = p + v dt + a dt^2 / 2 (eq. (14)-(16))
        dR = so3_exp(gyro * dt)
        self.p += self.v * dt + (0.5 * dt * dt) * a_world
        self.v += a_world * dt
        np.matmul(R, dR, out=self._r3)
        R[:] = self._r3
        # covariance: P+ = Phi (P + Q_hat dt) Phi^T, Phi = I + A dt + A^2 dt^2 / 2 (A^3 = 0)
        if dt != self._phi_dt:
            self._phi_dt = dt
            phi = self._phi
            phi[VEL, ROT] = self._g_skew * dt
            phi[POS, ROT] = self._g_skew * (0.5 * dt * dt)
            phi[POS, VEL] = np.eye(3) * dt
        P = self.P
        qd *= dt
        P += qd
        np.matmul(self._phi, P, out=self._tmp)
        np.matmul(self._tmp, self._phi.T, out=P)
        self._steps += 1
        if self._steps % 1000 == 0:  # keep R on SO(3) against round-off
            u, _, vt = np.linalg.svd(R)
            R[:] = u @ vt

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
        if not (c0 or c1):
            return
        key = (c0, c1)
        H, HT, N = self._H[key]
        R, P = self.R, self.P
        # z = R h_k + p - d_k for each contact foot, stacked
        rh = h @ R.T  # (2, 3): R h_k
        rh += self.p
        rh -= self.d
        z = rh[0] if key == (True, False) else rh[1] if key == (False, True) else rh.reshape(6)
        PHt = P @ HT
        S = H @ PHt
        S += N
        K = np.linalg.solve(S, PHt.T).T  # S symmetric: K = P H^T S^-1
        delta = K @ z
        # X+ = exp(delta) X (left multiplication for the right-invariant error)
        dR, jl = so3_exp_and_jl(delta[ROT])
        np.matmul(dR, R, out=self._r3)
        R[:] = self._r3
        blocks = self._blocks  # v, p, dL, dR as rows of a (4, 3) array
        blocks[0], blocks[1], blocks[2:4] = self.v, self.p, self.d
        upd = blocks @ dR.T + delta[3:].reshape(4, 3) @ jl.T
        self.v[:], self.p[:] = upd[0], upd[1]
        self.d[:] = upd[2:4]
        # P+ = (I - K H) P = P - K (H P); H P = (P H^T)^T
        P -= K @ PHt.T
        np.add(P, P.T, out=self._tmp)
        np.multiply(self._tmp, 0.5, out=P)
