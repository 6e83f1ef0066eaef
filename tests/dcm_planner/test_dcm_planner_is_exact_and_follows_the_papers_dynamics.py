"""The DCM planner (Xiang et al., (8)-(23)): its states follow the step-to-step recursion,
its search over the shared footstep engine finds the MIQP's global optimum (against an
exhaustive enumeration of the literal big-M form here, against Gurobi when it is installed),
and its plan keeps every constraint."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from processes.dcm_planner.params import VARIANTS, DcmParams
from processes.dcm_planner.problem import DcmInputs, DcmModel, sagittal_bound
from processes.dcm_planner.solver import DcmSolver
from processes.mpfc.params import MpfcParams
from processes.mpfc.solver import MpfcSolver
from runtime.config import HW_CONFIG_DIR
from runtime.params import load
from tools.testbed.gurobi_reference import (
    GurobiBackend,
    exhaustive_reference,
    gurobi_available,
)
from tools.testbed.mpfc_instances import random_instance

GAINS = HW_CONFIG_DIR / "gains" / "dcm_planner.yaml"


def _params(variant: str = "A") -> DcmParams:
    return dataclasses.replace(load(DcmParams, GAINS), variant=variant, time_limit_ms=1e6)


def _instances(count: int, seed: int, m_max: int):
    model = MpfcSolver(load(MpfcParams, HW_CONFIG_DIR / "gains" / "mpfc.yaml",
                            "simulation")).model
    rng = np.random.default_rng(seed)
    for _ in range(count):
        yield random_instance(rng, model, int(rng.integers(1, m_max + 1)))


def _integrate(xi: np.ndarray, t0: float, t1: float, cop, lam: float) -> np.ndarray:
    """xi' = lambda (xi - p(t)) from t0 to t1, RK4 in 1 ms steps (the check's own)."""
    n = max(round((t1 - t0) / 1e-3), 1)
    h = (t1 - t0) / n
    t = t0
    for _ in range(n):
        f = lambda tt, x: lam * (x - cop(tt))  # noqa: E731
        k1 = f(t, xi)
        k2 = f(t + h / 2, xi + h / 2 * k1)
        k3 = f(t + h / 2, xi + h / 2 * k2)
        k4 = f(t + h, xi + h * k3)
        xi = xi + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        t += h
    return xi


def _ramp(p_prev: np.ndarray, p_k: np.ndarray, d: float):
    """The OSC's CoP: from p_prev to p_k on a line over the first d seconds, then at p_k."""
    return lambda t: p_k + (p_prev - p_k) * max(1.0 - t / d, 0.0) if d > 0 else p_k


@pytest.mark.parametrize("t_ds", [0.0, 0.1])
def test_the_states_follow_the_step_to_step_dynamics_with_the_double_stance_ramp(t_ds):
    """With t_ds_s = 0 the paper's (8)/(12) exactly; with Cassie's 0.1 s double stance, the
    DCM of xi' = lambda (xi - p) under the OSC's CoP ramp, integrated step by step."""
    p = dataclasses.replace(_params(), t_ds_s=t_ds)
    model = DcmModel(p)
    z1, p0 = np.array([0.05, -0.08]), np.array([-0.12, 0.2])
    e_mat, e_vec = model.states(z1, p0)
    rng = np.random.default_rng(0)
    z = np.concatenate([[math.exp(p.lam * 0.45), 0.0], rng.normal(0.0, 0.3, 2 * model.F)])
    steps = [p0, np.zeros(2), *z[2:].reshape(model.F, 2)]  # p_0, p_1 = 0, p_2..p_N
    durations = [0.45] + [p.t_nom_s] * (model.N - 1)
    want = z1
    for k in range(1, model.N + 1):
        np.testing.assert_allclose(e_mat[k] @ z + e_vec[k], want, atol=1e-9)
        if t_ds == 0.0:  # (8): xi_{k+1} = sigma_k xi_k + (1 - sigma_k) p_k
            sig = math.exp(p.lam * durations[k - 1])
            want = sig * want + (1.0 - sig) * steps[k]
        else:
            want = _integrate(want, 0.0, durations[k - 1], _ramp(steps[k - 1], steps[k], t_ds),
                              p.lam)
    np.testing.assert_allclose(e_mat[model.N + 1] @ z + e_vec[model.N + 1], want, atol=1e-9)


def test_the_measured_dcm_is_carried_back_to_the_steps_start_through_the_ramp():
    """(22)-(23): the DCM measured in single stance t~ into the step, or in a double stance
    (the start's longer one too), is taken to the z_1 from which the model's step map
    reproduces it."""
    from processes.mpfc.solver import SupportTransfer

    p = _params()
    solver = DcmSolver(p)
    x = np.array([0.02, -0.05, 1.3, 9.0])
    xi = solver.dcm_of(x)
    mhl = solver.mass_kg * p.com_height_m * p.lam
    np.testing.assert_allclose(xi, [0.02 + 9.0 / mhl, -0.05 - 1.3 / mhl])
    foothold = [_flat()]
    prev = np.array([-0.15, 0.22, 0.0])
    # single stance, 0.25 s into the step: forward from z_1 through the ramp gives xi back
    solver.solve(x, "left", np.zeros(3), p.t_nom_s - 0.25, np.array([0.3, 0.0]), foothold,
                 transfer=SupportTransfer(prev, 0.0, p.t_ds_s))
    z1 = solver.last_inputs.z1
    np.testing.assert_allclose(
        _integrate(z1, 0.0, 0.25, _ramp(prev[:2], np.zeros(2), p.t_ds_s), p.lam), xi,
        atol=1e-9)
    # the start's 0.4 s double stance, 0.1 s in: its ramp to the liftoff, then the template's
    left, length = 0.3, 0.4
    solver.solve(x, "left", np.zeros(3), p.t_nom_s, np.array([0.3, 0.0]), foothold,
                 transfer=SupportTransfer(prev, left, length))
    lift = _integrate(xi, length - left, length, _ramp(prev[:2], np.zeros(2), length), p.lam)
    z1 = solver.last_inputs.z1
    np.testing.assert_allclose(
        _integrate(z1, 0.0, p.t_ds_s, _ramp(prev[:2], np.zeros(2), p.t_ds_s), p.lam), lift,
        atol=1e-9)


def _flat():
    from runtime.geometry import Foothold

    big = 50.0
    return Foothold.from_polygon(np.array([[-big, -big], [big, -big], [big, big], [-big, big]]))


@pytest.mark.parametrize("variant", VARIANTS)
def test_the_search_equals_the_exhaustive_optimum_of_the_literal_miqp(variant):
    p = _params(variant)
    checked = 0
    for inst in _instances(20, seed=3 + VARIANTS.index(variant), m_max=4):
        s = DcmSolver(p)
        sol = s.solve(inst.x_alip, inst.stance, inst.p_stance, inst.t_remaining_s, inst.vdes,
                      inst.footholds, inst.yaw)
        d = s.model.build_miqp(s.last_inputs, s.last_local)
        best, _, failed = exhaustive_reference(d)
        assert failed == 0
        if math.isinf(best):
            assert sol.status == "infeasible"
            continue
        checked += 1
        assert sol.status == "optimal"
        assert abs(sol.objective - best) <= 1e-6 * max(abs(best), 1.0), (sol.objective, best)
    assert checked >= 3


def test_a_plan_keeps_the_constraints_it_was_solved_under():
    p = _params()
    tol = 1e-6
    plans = 0
    for inst in _instances(40, seed=21, m_max=8):
        s = DcmSolver(p)
        sol = s.solve(inst.x_alip, inst.stance, inst.p_stance, inst.t_remaining_s, inst.vdes,
                      inst.footholds, inst.yaw)
        if not sol.has_plan:
            continue
        plans += 1
        inp = s.last_inputs
        states = sol.alip_states  # z_1..z_{N+1}
        steps = [np.zeros(2)] + [(_rot(inst.yaw).T @ (f - inst.p_stance))[:2]
                                 for f in sol.footsteps]
        for k in range(2, s.model.N + 1):
            side = (-1.0) ** (k + inp.ell)
            assert side * (states[k - 1][1] - steps[k - 1][1]) >= p.delta_y_m - tol  # (15)
            assert abs(states[k - 1][0] - steps[k - 1][0]) <= sagittal_bound(p) + tol  # (16)
        for k in range(1, s.model.N):
            assert states[k][0] - states[k - 1][0] <= p.l_max_m + tol  # (17)
            dx = steps[k][0] - steps[k - 1][0]
            dy = (-1.0) ** (k + inp.ell) * (steps[k][1] - steps[k - 1][1])
            assert p.l_min_m - tol <= dx <= p.l_max_m + tol  # (19)
            assert p.w_min_m - tol <= dy <= p.w_max_m + tol
        for k, i in enumerate(sol.foothold_indices):  # (18): on its foothold
            assert inst.footholds[i].contains_xy(*sol.footsteps[k][:2], tol=1e-6)
        assert p.t_min_s - tol <= sol.first_stance_ss_duration_s <= p.t_max_s + tol  # (13)
    assert plans >= 10


def _rot(yaw: float) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


@pytest.mark.skipif(not gurobi_available(), reason="gurobipy not installed or unlicensed")
def test_gurobi_agrees_with_the_search():
    g = GurobiBackend()
    p = _params()
    for inst in _instances(30, seed=5, m_max=12):
        s = DcmSolver(p)
        sol = s.solve(inst.x_alip, inst.stance, inst.p_stance, inst.t_remaining_s, inst.vdes,
                      inst.footholds, inst.yaw)
        gr = g.solve(s.model.build_miqp(s.last_inputs, s.last_local))
        assert (sol.status == "infeasible") == (gr.status == "infeasible")
        if sol.status == "optimal":
            assert abs(sol.objective - gr.objective) <= 1e-5 * max(abs(gr.objective), 1.0)


def test_the_start_checks_report_what_no_decision_can_change():
    p = _params()
    inp = DcmInputs(np.array([0.0, 0.1]), np.zeros(2), 0.0, ell=0)  # left stance, DCM left
    assert any("(15)" in v for v in inp.start_violations(p))
    inp = DcmInputs(np.array([0.0, -0.1]), np.zeros(2), 0.0, ell=0)
    assert inp.start_violations(p) == []


def test_a_bad_gains_file_names_file_key_and_allowed(tmp_path):
    from runtime.errors import ConfigError

    bad = tmp_path / "dcm.yaml"
    bad.write_text(GAINS.read_text() + "t_nominal_s: 0.4\n")
    with pytest.raises(ConfigError, match="t_nominal_s: unknown key"):
        load(DcmParams, bad)
    bad.write_text(GAINS.read_text().replace("variant: A", "variant: E"))
    with pytest.raises(ConfigError, match=r"variant: 'E' is not one of the allowed values"):
        load(DcmParams, bad)
