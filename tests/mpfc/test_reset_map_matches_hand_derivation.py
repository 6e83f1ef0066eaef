"""The reset map (2)-(9), (28) against closed forms derived by hand and against integrating
the double-stance dynamics (4) numerically."""

from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp
from scipy.linalg import expm

from processes.mpfc import alip


def _constants(model):
    p = model.params
    omega = np.sqrt(p.gravity_mps2 / p.com_height_m)
    return p, omega, p.mass_kg * p.gravity_mps2, p.t_ds_s


def test_linear_transfer_b_ds_matches_hand_closed_form(model) -> None:
    """(7), sagittal plane, f = t/T: by hand, with w = sqrt(g/H),
    dx(T)/dpx = 1 - sinh(wT)/(wT) and dLy(T)/dpx = -mg (cosh(wT) - 1)/(w^2 T)."""
    p, w, mg, t = _constants(model)
    a = alip.alip_a(p.mass_kg, p.com_height_m, p.gravity_mps2)
    bds = alip.b_ds_linear(a, t, alip.b_cop(p.mass_kg, p.gravity_mps2))
    assert np.isclose(bds[0, 0], 1.0 - np.sinh(w * t) / (w * t), rtol=1e-9)
    assert np.isclose(bds[3, 0], -mg * (np.cosh(w * t) - 1.0) / (w**2 * t), rtol=1e-9)
    assert np.allclose(bds[:, 2], 0.0)  # height never enters


def test_instant_transfer_b_ds_matches_hand_closed_form(model) -> None:
    """(28), coronal plane, f = 1: by hand dy(T)/dpy = -(cosh(wT) - 1) and
    dLx(T)/dpy = mg sinh(wT)/w."""
    p, w, mg, t = _constants(model)
    a = alip.alip_a(p.mass_kg, p.com_height_m, p.gravity_mps2)
    bds = alip.b_ds_instant(a, t, alip.b_cop(p.mass_kg, p.gravity_mps2))
    assert np.isclose(bds[1, 1], -(np.cosh(w * t) - 1.0), rtol=1e-9)
    assert np.isclose(bds[2, 1], mg * np.sinh(w * t) / w, rtol=1e-9)


def test_hardware_b_ds_takes_coronal_rows_from_28_and_sagittal_from_7(model) -> None:
    """Appendix A: the model's B_ds mixes (28) (rows y, L_x) and (7) (rows x, L_y)."""
    p, _, _, t = _constants(model)
    a, bc = model.alip.A, alip.b_cop(p.mass_kg, p.gravity_mps2)
    lin, inst = alip.b_ds_linear(a, t, bc), alip.b_ds_instant(a, t, bc)
    assert np.allclose(model.alip.B_ds[[0, 3]], lin[[0, 3]])
    assert np.allclose(model.alip.B_ds[[1, 2]], inst[[1, 2]])
    assert not np.allclose(lin[[1, 2]], inst[[1, 2]])  # the choice matters


def _integrate_double_stance(model, x_minus, p_minus, p_plus, f):
    """Integrate (1) with the CoP as a virtual contact point, (2)-(3), over T_ds."""
    p = model.params
    mg = p.mass_kg * p.gravity_mps2

    def rhs(t, x):
        cop = p_minus + np.array([f[0](t), f[1](t), 0.0]) * (p_plus - p_minus)
        dx = model.alip.A @ x
        dx[2] += mg * (cop[1] - p_minus[1])  # (3): dLx = -mg (y - y_cop), x relative to p_-
        dx[3] += -mg * (cop[0] - p_minus[0])
        return dx

    sol = solve_ivp(rhs, (0.0, p.t_ds_s), x_minus, rtol=1e-11, atol=1e-12)
    return sol.y[:, -1]


def test_reset_map_matches_numerical_integration(model) -> None:
    """(9) equals integrating (4) (linear sagittal, instant coronal transfer) then (8)."""
    p = model.params
    rng = np.random.default_rng(0)
    t_ds = p.t_ds_s
    f = (lambda t: t / t_ds, lambda t: 1.0)
    for _ in range(5):
        x_minus = rng.normal(0, 1, 4) * np.array([0.1, 0.1, 10.0, 10.0])
        p_minus = rng.normal(0, 0.3, 3)
        p_plus = p_minus + rng.normal(0, 0.3, 3)
        x_ds = _integrate_double_stance(model, x_minus, p_minus, p_plus, f)
        x_plus = x_ds.copy()
        x_plus[:2] -= (p_plus - p_minus)[:2]  # (8)
        pred = model.alip.A_r @ x_minus + model.alip.B_r @ (p_plus - p_minus)
        assert np.allclose(pred, x_plus, rtol=1e-7, atol=1e-8)


def test_linear_transfer_reset_map_matches_integration() -> None:
    """With lateral_instant=False, (7) alone describes linear transfer in both planes."""
    model_lin = alip.AlipModel.build(33.3, 0.85, 9.81, 0.3, 0.1, lateral_instant=False)

    class _M:
        params = type("P", (), {"mass_kg": 33.3, "gravity_mps2": 9.81, "t_ds_s": 0.1})
        alip = model_lin

    f = (lambda t: t / 0.1, lambda t: t / 0.1)
    x_minus = np.array([0.05, -0.1, 3.0, 12.0])
    p_minus, p_plus = np.zeros(3), np.array([0.25, -0.2, 0.05])
    x_plus = _integrate_double_stance(_M, x_minus, p_minus, p_plus, f)
    x_plus[:2] -= p_plus[:2]
    pred = model_lin.A_r @ x_minus + model_lin.B_r @ p_plus
    assert np.allclose(pred, x_plus, rtol=1e-7, atol=1e-8)
    assert np.allclose(model_lin.A_r, expm(model_lin.A * 0.1))
