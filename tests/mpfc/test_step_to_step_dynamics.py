"""Step-to-step dynamics (10) and the linearised first-stance timing (11)-(12)."""

from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp
from scipy.linalg import expm


def test_s2s_matrices_are_reset_then_single_stance(model) -> None:
    """(10): A_s2s = exp(A (T_ss + T_ds)), B_s2s = exp(A T_ss) B_r."""
    a, p = model.alip.A, model.params
    assert np.allclose(model.alip.A_s2s, expm(a * (p.t_ss_s + p.t_ds_s)))
    assert np.allclose(model.alip.B_s2s, expm(a * p.t_ss_s) @ model.alip.B_r)


def test_s2s_step_matches_integrating_single_stance(model) -> None:
    """Reset (9) then integrating (1) with u = 0 for T_ss gives (10)'s prediction."""
    x0 = np.array([0.12, -0.05, 4.0, 15.0])
    dp = np.array([0.3, 0.2, 0.1])
    x_plus = model.alip.A_r @ x0 + model.alip.B_r @ dp
    sol = solve_ivp(lambda t, x: model.alip.A @ x, (0, model.params.t_ss_s), x_plus,
                    rtol=1e-11, atol=1e-12)
    assert np.allclose(model.alip.s2s_step(x0, np.zeros(3), dp), sol.y[:, -1], rtol=1e-7)


def test_closed_form_exponential_matches_scipy(model) -> None:
    """The cosh/sinh exp(A t) used per solve equals scipy's expm."""
    for t in (-0.3, 0.0, 0.05, 0.4):
        assert np.allclose(model.expm_a(t), expm(model.alip.A * t), rtol=1e-12, atol=1e-12)


def test_initial_state_linearisation_is_exact_in_u_and_first_order_in_t(model) -> None:
    """(12): x_0 is exact in u (the ankle torque enters (11) linearly) and its error in T is
    second order: halving dT quarters the error."""
    x_c = np.array([0.03, 0.08, -5.0, 10.0])
    t_star, u = 0.2, 7.0
    a0, b_t, b_u = model.alip.initial_state_linearisation(x_c, t_star)

    def exact(t: float, u_: float) -> np.ndarray:
        sol = solve_ivp(lambda _, x: model.alip.A @ x + model.alip.B * u_, (0, t), x_c,
                        rtol=1e-12, atol=1e-12)
        return sol.y[:, -1]

    assert np.allclose(a0 + b_u * u, exact(t_star, u), rtol=1e-8, atol=1e-8)
    errs = [np.linalg.norm(a0 + b_t * dt - exact(t_star + dt, 0.0)) for dt in (0.02, 0.01)]
    assert 3.5 < errs[0] / errs[1] < 4.5
