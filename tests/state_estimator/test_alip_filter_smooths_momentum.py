"""The ALIP Kalman filter (Section IX-A-2): smoother angular momentum, faithful CoM, resets."""

from __future__ import annotations

import numpy as np
from scipy.linalg import expm

from processes.state_estimator.alip_filter import AlipFilterParams, AlipKalman, alip_a

MASS, H, G, DT = 33.3, 0.85, 9.81, 5e-4


def _truth(x0: np.ndarray, n: int) -> np.ndarray:
    f = expm(alip_a(MASS, H, G) * DT)
    xs = np.empty((n, 4))
    x = x0.copy()
    for k in range(n):
        xs[k] = x
        x = f @ x
    return xs


def test_filter_cuts_momentum_noise_and_keeps_com_position():
    rng = np.random.default_rng(7)
    n = 600  # 0.3 s single stance
    truth = _truth(np.array([-0.08, 0.1, -3.0, 2.0]), n)
    noise = np.column_stack([rng.normal(0, 0.002, (n, 2)), rng.normal(0, 2.0, (n, 2))])
    # impact-like spikes in the lateral momentum (the paper's motivation)
    noise[200:210, 2] += 15.0
    meas = truth + noise
    kf = AlipKalman(MASS, AlipFilterParams(height=H), G)
    out = np.array([kf.step(z, 0, DT).copy() for z in meas])
    raw_err = np.abs(meas - truth)[50:]
    est_err = np.abs(out - truth)[50:]
    assert np.sqrt((est_err[:, 2:] ** 2).mean()) < 0.5 * np.sqrt((raw_err[:, 2:] ** 2).mean())
    assert est_err[150:250, 2].max() < 0.5 * raw_err[150:250, 2].max()  # spike suppressed
    assert est_err[:, :2].max() < 0.01  # CoM follows its (precise) measurement


def test_stance_switch_restarts_from_the_measurement():
    kf = AlipKalman(MASS, AlipFilterParams(height=H), G)
    for _ in range(100):
        kf.step(np.array([0.05, -0.1, 1.0, 2.0]), 0, DT)
    z = np.array([-0.2, 0.1, -4.0, 3.0])  # the reset map's jump: new stance foot
    np.testing.assert_allclose(kf.step(z, 1, DT), z)
    assert kf.stance == 1
