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

The propagation and correction are compiled (numba, cached on disk; ``kernels``) and work in
place on the preallocated state: at 2 kHz, numpy's per-call cost on 3- and 15-element arrays
was most of the filter's time (about 0.19 ms per packet, now about 0.01 ms).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from runtime.params import spec

from .kernels import DIM, _correct, _correct_still, _propagate

#: state slices (rows of the 15-dim error)
ROT, VEL, POS = slice(0, 3), slice(3, 6), slice(6, 9)
FOOT = (slice(9, 12), slice(12, 15))


@dataclass(frozen=True)
class InEKFNoise:
    """Continuous-time noise densities (std devs) and initial uncertainty of the InEKF."""

    gyro: float = spec(0.002, lo=0.0, lo_open=True, unit="rad/s/sqrt(Hz)")
    accel: float = spec(0.04, lo=0.0, lo_open=True, unit="m/s^2/sqrt(Hz)")
    contact: float = spec(0.01, lo=0.0, lo_open=True, unit="m/s/sqrt(Hz)")  # a planted foot's slip
    swing: float = spec(1.0, lo=0.0, lo_open=True, unit="m/s/sqrt(Hz)")  # a foot not in contact
    #: leg kinematics (encoders, spring model) per axis
    kinematics: float = spec(0.005, lo=0.0, lo_open=True, unit="m")
    init_rot: float = spec(0.02, lo=0.0, lo_open=True, unit="rad")
    init_vel: float = spec(0.1, lo=0.0, lo_open=True, unit="m/s")
    init_pos: float = spec(0.01, lo=0.0, lo_open=True, unit="m")


@dataclass(frozen=True)
class StillParams:
    """Zero-velocity updates while the robot hangs at rest with no foot down (the start-up
    holder, a gantry): ``kernels._correct_still``. At rest means every IMU sample within
    ``gyro_rad_s`` of no rotation and ``accel_m_s2`` of a specific force of g, for
    ``after_s``; the update then measures the body velocity as 0 with ``velocity_std_m_s``."""

    gyro_rad_s: float = spec(0.1, lo=0.0, lo_open=True, unit="rad/s")
    accel_m_s2: float = spec(0.5, lo=0.0, lo_open=True, unit="m/s^2")
    after_s: float = spec(0.25, lo=0.0, lo_open=True, unit="s")
    velocity_std_m_s: float = spec(0.01, lo=0.0, lo_open=True, unit="m/s")


def skew(w: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """The 3x3 cross-product matrix [w]x."""
    s = np.zeros((3, 3)) if out is None else out
    s[0, 1], s[0, 2] = -w[2], w[1]
    s[1, 0], s[1, 2] = w[2], -w[0]
    s[2, 0], s[2, 1] = -w[1], w[0]
    return s


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
        """Compile (or load from the on-disk cache) the kernels now, not on the first packet."""
        R, v, p, d, P = np.eye(3), np.zeros(3), np.zeros(3), np.zeros((2, 3)), np.eye(DIM)
        _propagate(R, v, p, d, P, np.zeros(3), np.zeros(3), 5e-4, self.g, 1.0, 1.0, 1.0, 1.0,
                   self._scratch)
        _correct(R, v, p, d, P, np.zeros((2, 3)), True, False, 1e-4)
        _correct_still(R, v, p, d, P, 1e-4)

    # -- set-up -----------------------------------------------------------------------------
    def reset(self, R: np.ndarray, v: np.ndarray, p: np.ndarray) -> None:
        """Start from orientation ``R``, velocity ``v`` and position ``p`` (IMU, world)."""
        n = self.noise
        self.R[:] = R
        self.v[:] = v
        self.p[:] = p
        self.d[:] = p
        self.contact[0] = self.contact[1] = False  # in place: it may be a view (fused step)
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

    def correct_still(self, velocity_var: float) -> None:
        """Zero-velocity update (the robot at rest with no foot down): ``R^T v`` measured 0."""
        _correct_still(self.R, self.v, self.p, self.d, self.P, velocity_var)
