"""Appendix B: the projections Pi_n and offsets d_n of (17), against 2-step periodic orbits
built directly from (16)."""

from __future__ import annotations

import numpy as np


def _periodic_orbit(model, v: np.ndarray, dp0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Solve (16) for x_0 given dp0 (dp1 = 2 T v - dp0), then step once with (10)."""
    a, b = model.alip.A_s2s, model.alip.B_s2s[:, :2]
    t = model.params.t_s2s_s
    dp1 = 2 * t * v - dp0
    x0 = np.linalg.solve(np.eye(4) - a @ a, a @ b @ dp0 + b @ dp1)
    x1 = a @ x0 + b @ dp0
    assert np.allclose(a @ x1 + b @ dp1, x0)  # really period 2
    return x0, x1


def test_projections_are_orthogonal_rank_two(model) -> None:
    """Pi_n is a symmetric idempotent of rank 2 annihilating L_n."""
    vs = model.vs
    for pi, basis in ((vs.Pi0, vs.L0), (vs.Pi1, vs.L1)):
        assert np.allclose(pi, pi.T)
        assert np.allclose(pi @ pi, pi)
        assert np.linalg.matrix_rank(pi, tol=1e-9) == 2
        assert np.allclose(pi @ basis, 0.0, atol=1e-9)


def test_periodic_orbits_with_desired_velocity_have_zero_cost(model) -> None:
    """Every 2-periodic orbit with net displacement 2 T v satisfies Pi_n (x_n - d_n) = 0."""
    rng = np.random.default_rng(1)
    vs = model.vs
    for _ in range(10):
        v = rng.uniform(-1, 1, 2)
        x0, x1 = _periodic_orbit(model, v, rng.uniform(-0.4, 0.4, 2))
        assert np.allclose(vs.Pi0 @ (x0 - vs.D0 @ v), 0.0, atol=1e-9)
        assert np.allclose(vs.Pi1 @ (x1 - vs.D1 @ v), 0.0, atol=1e-9)


def test_orbits_at_other_velocities_are_penalised(model) -> None:
    """An orbit with a different velocity is off the subspace (the cost can tell them apart)."""
    vs = model.vs
    x0, _ = _periodic_orbit(model, np.array([0.5, 0.0]), np.array([0.2, -0.2]))
    assert np.linalg.norm(vs.Pi0 @ (x0 - vs.D0 @ np.array([0.0, 0.0]))) > 1e-3


def test_offset_maps_follow_appendix_b(model) -> None:
    """(30)-(31): d_0 = 2 T G B v and d_1 = A d_0, with G = (I - A^2)^-1."""
    a, b = model.alip.A_s2s, model.alip.B_s2s[:, :2]
    g = np.linalg.inv(np.eye(4) - a @ a)
    t = model.params.t_s2s_s
    assert np.allclose(model.vs.D0, 2 * t * g @ b)
    assert np.allclose(model.vs.D1, a @ model.vs.D0)
    assert np.allclose(model.vs.L1, a @ model.vs.L0 + b)
