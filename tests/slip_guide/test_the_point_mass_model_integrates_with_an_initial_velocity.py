"""Eqs. (1)-(2) with the initial velocity the paper leaves out: the double-integration matrix
reproduces a hand-integrated point mass, and the QP's CoM path is that integral of its own
contact accelerations."""

from __future__ import annotations

import numpy as np

from processes.slip_guide.model import double_integration_matrix, rollout


def test_the_matrix_is_the_papers_with_t_squared_folded_in() -> None:
    p = double_integration_matrix(4, 0.5)
    expected = 0.25 * np.array([[0.5, 0, 0, 0], [1.5, 0.5, 0, 0], [2.5, 1.5, 0.5, 0],
                                [3.5, 2.5, 1.5, 0.5]])  # rows 1/2 .. (2N - 1)/2 of (1)
    np.testing.assert_allclose(p, expected)


def test_it_reproduces_a_hand_integrated_point_mass_with_an_initial_velocity() -> None:
    rng = np.random.default_rng(3)
    dt, n = 0.15, 12
    acc = rng.normal(0.0, 3.0, (n, 3)) + np.array([0.0, 0.0, -9.81])
    s0, v0 = np.array([0.1, -0.2, 0.85]), np.array([0.32, 0.05, -0.1])
    s, v = rollout(s0, v0, acc, dt)
    # by hand: constant acceleration over each interval
    hs, hv = [s0], [v0]
    for a in acc:
        hs.append(hs[-1] + dt * hv[-1] + 0.5 * dt * dt * a)
        hv.append(hv[-1] + dt * a)
    np.testing.assert_allclose(s, np.array(hs), atol=1e-12)
    np.testing.assert_allclose(v, np.array(hv), atol=1e-12)


def test_the_plans_com_path_is_the_double_integral_of_its_contact_forces(plan_of,
                                                                         slip_params) -> None:
    plan = plan_of("stones", 3.0)
    n = len(plan.s) - 1
    acc = np.zeros((n, 3))
    np.add.at(acc, plan.step, plan.accel)  # (13): alpha (s~ - f_p), summed per time step
    acc += slip_params.gravity
    s, v = rollout(plan.s[0], plan.v[0], acc, slip_params.dt_s)
    np.testing.assert_allclose(plan.s, s, atol=1e-5)
    np.testing.assert_allclose(plan.v, v, atol=1e-5)
