"""The compiled InEKF against Hartley et al.'s equations written out with dense matrices.

The oracle builds the 7 x 7 group element of SE_4(3), its 15 x 15 adjoint, ``A`` of eq. (26),
``Phi = expm(A dt)``, the measurement Jacobian of eq. (40) and the group exponential as
``expm`` of the Lie-algebra matrix: nothing of the filter's closed forms is reused.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import expm

from processes.state_estimator.inekf import DIM, ContactInEKF, InEKFNoise

G = 9.81
DT = 5e-4


def _hat(w: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])


def _group(f: ContactInEKF) -> np.ndarray:
    """X = [[R, v, p, dL, dR], [0, I]] (7 x 7)."""
    x = np.eye(7)
    x[:3, :3] = f.R
    x[:3, 3], x[:3, 4], x[:3, 5], x[:3, 6] = f.v, f.p, f.d[0], f.d[1]
    return x


def _adjoint(f: ContactInEKF) -> np.ndarray:
    """Ad_X of SE_4(3): R on the diagonal blocks, [x]x R below the rotation block."""
    ad = np.zeros((DIM, DIM))
    for i in range(5):
        ad[3 * i : 3 * i + 3, 3 * i : 3 * i + 3] = f.R
    for i, x in enumerate((f.v, f.p, f.d[0], f.d[1]), start=1):
        ad[3 * i : 3 * i + 3, 0:3] = _hat(x) @ f.R
    return ad


def _algebra(xi: np.ndarray) -> np.ndarray:
    """The 7 x 7 Lie-algebra matrix of xi = (phi, xi_v, xi_p, xi_dL, xi_dR)."""
    a = np.zeros((7, 7))
    a[:3, :3] = _hat(xi[0:3])
    for i in range(4):
        a[:3, 3 + i] = xi[3 + 3 * i : 6 + 3 * i]
    return a


def _random_filter(rng: np.random.Generator, contact: tuple[bool, bool]) -> ContactInEKF:
    f = ContactInEKF(InEKFNoise(), G)
    f.reset(expm(_hat(rng.normal(size=3) * 0.4)), rng.normal(size=3) * 0.3,
            np.array((0.1, -0.2, 1.0)) + rng.normal(size=3) * 0.1)
    f.d[:] = f.p + rng.normal(size=(2, 3)) * 0.5
    m = rng.normal(size=(DIM, DIM)) * 0.05
    f.P[:] = m @ m.T + 1e-4 * np.eye(DIM)
    f.contact = list(contact)
    return f


@pytest.mark.parametrize("contact", [(False, False), (True, False), (True, True)])
def test_propagation_is_hartley_eq_26_27_discretised(contact):
    rng = np.random.default_rng(1)
    f = _random_filter(rng, contact)
    n = f.noise
    gyro, accel = rng.normal(size=3), rng.normal(size=3) + np.array((0.0, 0.0, G))
    X0, P0, ad = _group(f), f.P.copy(), _adjoint(f)
    f.propagate(gyro, accel, DT)
    # mean (eq. (14)-(16))
    g = np.array((0.0, 0.0, -G))
    a = X0[:3, :3] @ accel + g
    np.testing.assert_allclose(f.R, X0[:3, :3] @ expm(_hat(gyro * DT)), atol=1e-14)
    np.testing.assert_allclose(f.v, X0[:3, 3] + a * DT, atol=1e-14)
    np.testing.assert_allclose(f.p, X0[:3, 4] + X0[:3, 3] * DT + 0.5 * a * DT**2, atol=1e-14)
    np.testing.assert_array_equal(f.d, X0[:3, 5:7].T)
    # covariance: P+ = Phi (P + Ad Q Ad^T dt) Phi^T, Phi = expm(A dt)
    A = np.zeros((DIM, DIM))
    A[3:6, 0:3] = _hat(g)
    A[6:9, 3:6] = np.eye(3)
    phi = expm(A * DT)
    q = np.zeros(DIM)
    q[0:3], q[3:6] = n.gyro**2, n.accel**2
    for k in (0, 1):
        q[9 + 3 * k : 12 + 3 * k] = (n.contact if contact[k] else n.swing) ** 2
    expected = phi @ (P0 + ad @ np.diag(q) @ ad.T * DT) @ phi.T
    np.testing.assert_allclose(f.P, expected, rtol=1e-10, atol=1e-16)


@pytest.mark.parametrize("contact", [(True, False), (False, True), (True, True)])
def test_correction_is_the_right_invariant_update_of_eq_36_40(contact):
    rng = np.random.default_rng(2)
    f = _random_filter(rng, contact)
    h = rng.normal(size=(2, 3)) * 0.5
    X0, P0 = _group(f), f.P.copy()
    f.correct(h)
    feet = [k for k in (0, 1) if contact[k]]
    H = np.zeros((3 * len(feet), DIM))
    z = np.zeros(3 * len(feet))
    for i, k in enumerate(feet):
        H[3 * i : 3 * i + 3, 6:9] = -np.eye(3)
        H[3 * i : 3 * i + 3, 9 + 3 * k : 12 + 3 * k] = np.eye(3)
        z[3 * i : 3 * i + 3] = X0[:3, :3] @ h[k] + X0[:3, 4] - X0[:3, 5 + k]
    S = H @ P0 @ H.T + f.noise.kinematics**2 * np.eye(len(z))
    K = P0 @ H.T @ np.linalg.inv(S)
    X1 = expm(_algebra(K @ z)) @ X0
    np.testing.assert_allclose(_group(f), X1, atol=1e-12)
    np.testing.assert_allclose(f.P, (np.eye(DIM) - K @ H) @ P0, rtol=1e-9, atol=1e-14)
    np.testing.assert_allclose(f.P, f.P.T, atol=0.0)


def test_no_contact_leaves_the_state_alone_on_correction():
    f = _random_filter(np.random.default_rng(3), (False, False))
    X0, P0 = _group(f), f.P.copy()
    f.correct(np.ones((2, 3)))
    np.testing.assert_array_equal(_group(f), X0)
    np.testing.assert_array_equal(f.P, P0)


def test_zero_velocity_update_is_the_right_invariant_update_with_h_on_velocity():
    """Body velocity measured 0 (``Y = X^-1 b``, b the velocity column): ``H = [0, I, 0...]``,
    innovation ``-v``, the same group update as the leg kinematics."""
    f = _random_filter(np.random.default_rng(4), (False, False))
    X0, P0 = _group(f), f.P.copy()
    var = 0.01**2
    f.correct_still(var)
    H = np.zeros((3, DIM))
    H[:, 3:6] = np.eye(3)
    z = -X0[:3, 3]
    K = P0 @ H.T @ np.linalg.inv(H @ P0 @ H.T + var * np.eye(3))
    np.testing.assert_allclose(_group(f), expm(_algebra(K @ z)) @ X0, atol=1e-12)
    np.testing.assert_allclose(f.P, (np.eye(DIM) - K @ H) @ P0, rtol=1e-9, atol=1e-14)


@pytest.mark.parametrize("still", [False, True])
def test_a_minute_hanging_still_keeps_the_position_covariance_small(still):
    """Hung from the holder with no foot down, IMU at rest: dead reckoning alone lets the
    position std grow past 100 m in a minute (the first touchdown then threw the estimate
    metres off); with the zero-velocity updates it stays near its 1 cm start."""
    f = ContactInEKF(InEKFNoise(), G)
    f.reset(np.eye(3), np.zeros(3), np.array((0.0, 0.0, 1.0)))
    gyro, accel = np.zeros(3), np.array((0.0, 0.0, G))
    for _ in range(round(60.0 / DT)):
        f.propagate(gyro, accel, DT)
        if still:
            f.correct_still(0.01**2)
    pos_std = np.sqrt(np.diag(f.P)[6:9])
    if still:
        assert pos_std.max() < 0.02, pos_std
        assert np.sqrt(np.diag(f.P)[3:6]).max() < 0.01
    else:
        assert pos_std.max() > 100.0, pos_std
