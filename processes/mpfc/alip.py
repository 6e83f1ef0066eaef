"""ALIP model pieces of MPFC: continuous dynamics (1), reset map with double stance (2)-(9)
and the lateral adjustment (28), step-to-step dynamics (10), the linearised first-stance
timing (11)-(12) and the desired-velocity subspace of Appendix B (16)-(17), (29)-(31).

State ordering everywhere: x = [x_com, y_com, L_x, L_y] in the stance frame (CoM relative to
the stance foot, angular momentum about the contact point). Footstep differences are 3D
(x, y, z); the z column of every input matrix is zero because the ALIP ignores height.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import expm

# Indices of the sagittal (x_com, L_y) and coronal (y_com, L_x) state components.
SAGITTAL = (0, 3)
CORONAL = (1, 2)


def alip_a(mass: float, height: float, gravity: float) -> np.ndarray:
    """Continuous ALIP state matrix A of (1)."""
    mh = mass * height
    mg = mass * gravity
    return np.array(
        [
            [0.0, 0.0, 0.0, 1.0 / mh],
            [0.0, 0.0, -1.0 / mh, 0.0],
            [0.0, -mg, 0.0, 0.0],
            [mg, 0.0, 0.0, 0.0],
        ]
    )


def alip_b_ankle() -> np.ndarray:
    """Ankle-torque input column B of (1): sagittal ankle torque enters dL_y/dt."""
    return np.array([0.0, 0.0, 0.0, 1.0])


def b_cop(mass: float, gravity: float) -> np.ndarray:
    """B_CoP of (4): how a CoP displacement (x, y, z) enters dL_x/dt and dL_y/dt (from (3))."""
    mg = mass * gravity
    out = np.zeros((4, 3))
    out[2, 1] = mg
    out[3, 0] = -mg
    return out


def b_fp() -> np.ndarray:
    """B_fp of (8): the coordinate change of the CoM position to the new stance foot."""
    out = np.zeros((4, 3))
    out[0, 0] = -1.0
    out[1, 1] = -1.0
    return out


def b_ds_linear(a: np.ndarray, t_ds: float, bcop: np.ndarray) -> np.ndarray:
    """B_ds of (7): closed form of (6) for linear weight transfer f(t) = t / T_ds."""
    ar = expm(a * t_ds)
    ainv = np.linalg.inv(a)
    arinv = np.linalg.inv(ar)
    eye = np.eye(4)
    return ar @ ainv @ ((1.0 / t_ds) * ainv @ (eye - arinv) - arinv) @ bcop


def b_ds_instant(a: np.ndarray, t_ds: float, bcop: np.ndarray) -> np.ndarray:
    """B_ds of (28): closed form of (6) for instantaneous weight transfer f(t) = 1."""
    ar = expm(a * t_ds)
    return np.linalg.inv(a) @ (ar - np.eye(4)) @ bcop


def b_ds_hardware(a: np.ndarray, t_ds: float, bcop: np.ndarray) -> np.ndarray:
    """Appendix A: coronal rows (y_com, L_x) from (28), sagittal rows (x_com, L_y) from (7).

    A is block-decoupled into sagittal and coronal planes, so taking rows is the same as taking
    the inner 2x2 / corner entries of the 4x4 integral matrix the paper describes.
    """
    out = b_ds_linear(a, t_ds, bcop)
    inst = b_ds_instant(a, t_ds, bcop)
    out[list(CORONAL), :] = inst[list(CORONAL), :]
    return out


def reset_map(
    a: np.ndarray, t_ds: float, bcop: np.ndarray, lateral_instant: bool
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Reset map (9): returns (A_r, B_ds, B_r) with x_+ = A_r x_- + B_r (p_+ - p_-)."""
    ar = expm(a * t_ds)
    bds = b_ds_hardware(a, t_ds, bcop) if lateral_instant else b_ds_linear(a, t_ds, bcop)
    br = bds + b_fp()
    return ar, bds, br


def a_d(a: np.ndarray, t: float) -> np.ndarray:
    """A_d(T) = exp(A T) of (11)."""
    return expm(a * t)


def b_d(a: np.ndarray, t: float, b: np.ndarray) -> np.ndarray:
    """B_d(T) = A^{-1} (A_d(T) - I) B of (11): effect of a constant ankle torque over T."""
    return np.linalg.solve(a, (expm(a * t) - np.eye(4)) @ b)


@dataclass(frozen=True)
class AlipModel:
    """Constant ALIP matrices for one parameter set, built once (nothing here changes per solve).

    Attributes follow the paper's names: A (1), B (1), A_r/B_ds/B_r (5)-(9), A_s2s/B_s2s (10).
    """

    mass: float
    height: float
    gravity: float
    t_ss: float
    t_ds: float
    lateral_instant: bool
    A: np.ndarray
    B: np.ndarray
    A_r: np.ndarray
    B_ds: np.ndarray
    B_r: np.ndarray
    A_s2s: np.ndarray
    B_s2s: np.ndarray

    @classmethod
    def build(
        cls,
        mass: float,
        height: float,
        gravity: float,
        t_ss: float,
        t_ds: float,
        lateral_instant: bool = True,
    ) -> AlipModel:
        """Build (1), (9) and (10) for the given physical and gait-timing parameters."""
        a = alip_a(mass, height, gravity)
        ar, bds, br = reset_map(a, t_ds, b_cop(mass, gravity), lateral_instant)
        a_s2s = expm(a * (t_ss + t_ds))
        b_s2s = expm(a * t_ss) @ br
        for arr in (a, ar, bds, br, a_s2s, b_s2s):
            arr.setflags(write=False)
        return cls(
            mass, height, gravity, t_ss, t_ds, lateral_instant, a, alip_b_ankle(), ar, bds, br,
            a_s2s, b_s2s,
        )

    def initial_state_linearisation(
        self, x_c: np.ndarray, t_nominal: float
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(12)/(15b): x_0 = a0 + bT (T - T*) + bu u; returns (a0, bT, bu) about T*, u = 0."""
        ad = expm(self.A * t_nominal)
        a0 = ad @ x_c
        b_t = self.A @ a0  # dA_d/dT = A A_d(T*)
        b_u = np.linalg.solve(self.A, (ad - np.eye(4)) @ self.B)
        return a0, b_t, b_u

    def s2s_step(self, x_n: np.ndarray, p_n: np.ndarray, p_next: np.ndarray) -> np.ndarray:
        """(10): ALIP state at the end of the next stance, given the footsteps (3D)."""
        return self.A_s2s @ x_n + self.B_s2s @ (np.asarray(p_next) - np.asarray(p_n))


def projection_complement(basis: np.ndarray) -> np.ndarray:
    """Orthogonal projector onto span(basis)^perp (4x4, symmetric, idempotent)."""
    q, _ = np.linalg.qr(basis)
    return np.eye(basis.shape[0]) - q @ q.T


@dataclass(frozen=True)
class VelocitySubspace:
    """Appendix B: projections Pi_0, Pi_1 and offset maps D_0, D_1 with d_n = D_n v_des.

    Pi_{n+2} = Pi_n and d_{n+2} = d_n, so `pi(n)` and `offset(n, v)` index by parity.
    """

    L0: np.ndarray
    L1: np.ndarray
    Pi0: np.ndarray
    Pi1: np.ndarray
    D0: np.ndarray
    D1: np.ndarray

    @classmethod
    def build(cls, model: AlipModel) -> VelocitySubspace:
        """(29)-(31) with 2D footsteps (the z column of B_s2s is zero and dropped)."""
        a = model.A_s2s
        b = model.B_s2s[:, :2]
        t_s2s = model.t_ss + model.t_ds
        g = np.linalg.inv(np.eye(4) - a @ a)
        l0 = g @ (a - np.eye(4)) @ b  # (29): span of the free first step
        d0 = 2.0 * t_s2s * g @ b  # d_0(v) = 2 T_s2s G B_s2s v   (30)
        l1 = a @ l0 + b  # (31)
        d1 = a @ d0  # (31)
        return cls(l0, l1, projection_complement(l0), projection_complement(l1), d0, d1)

    def pi(self, n: int) -> np.ndarray:
        """Pi_n of (17)."""
        return self.Pi0 if n % 2 == 0 else self.Pi1

    def offset_map(self, n: int) -> np.ndarray:
        """D_n with d_n(v_des) = D_n v_des (17)."""
        return self.D0 if n % 2 == 0 else self.D1


def nominal_step(v_des: np.ndarray, sigma: float, t_s2s: float, width: float) -> np.ndarray:
    """delta p_n^* of (18): nominal step from the desired velocity and the step width."""
    return np.array([v_des[0] * t_s2s, v_des[1] * t_s2s + sigma * width, 0.0])
