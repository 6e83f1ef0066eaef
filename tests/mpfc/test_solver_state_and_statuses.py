"""Every solve ends optimal, time_limited or infeasible; state carries between solves; piqp
statuses other than solved/infeasible are retried, never taken as a verdict."""

from __future__ import annotations

import numpy as np
import piqp
import pytest
from mpfc_test_helpers import solve, with_params

from processes.mpfc import MpfcSolver
from runtime.geometry import Foothold
from tools.testbed.mpfc_instances import random_instance


def test_no_footholds_is_infeasible_without_a_plan(params) -> None:
    solver = MpfcSolver(params)
    sol = solver.solve(np.zeros(4), "left", np.zeros(3), 0.3, np.zeros(2), [])
    assert sol.status == "infeasible" and not sol.has_plan


def test_foothold_only_on_the_wrong_side_is_infeasible(params) -> None:
    """Left stance: the next (right) foot may not cross to the left (crossover constraint)."""
    left_only = Foothold.from_polygon(np.array([[0, 0.1], [0.4, 0.1], [0.4, 0.5], [0, 0.5]]))
    sol = MpfcSolver(params).solve(np.zeros(4), "left", np.zeros(3), 0.3, np.zeros(2),
                                   [left_only])
    assert sol.status == "infeasible"
    sol = MpfcSolver(params).solve(np.zeros(4), "right", np.zeros(3), 0.3, np.zeros(2),
                                   [left_only])
    assert sol.status != "infeasible"


def test_bad_stance_name_raises(params) -> None:
    with pytest.raises(ValueError):
        MpfcSolver(params).solve(np.zeros(4), "both", np.zeros(3), 0.3, np.zeros(2), [])


def test_time_limit_returns_time_limited(params) -> None:
    solver = MpfcSolver(with_params(params, time_limit_ms=1e-6))
    rng = np.random.default_rng(3)
    statuses = set()
    for _ in range(5):
        inst = random_instance(rng, solver.model, 12)
        statuses.add(solve(solver, inst).status)
    assert statuses <= {"time_limited", "infeasible"}
    assert "time_limited" in statuses


def test_trust_region_keeps_p1_near_the_previous_solution(params) -> None:
    """Late in stance (T* < 0.27 s) p_1 stays within T* metres of the previous p_1."""
    solver = MpfcSolver(params)
    ground = Foothold.from_polygon(np.array([[-3, -3], [3, -3], [3, 3], [-3, 3]], dtype=float))
    x = np.array([0.0, 0.05, 0.0, 8.0])
    first = solver.solve(x, "left", np.zeros(3), 0.2, np.array([0.3, 0.0]), [ground])
    assert first.has_plan and first.trust_region_active is False  # nothing to trust yet
    # a big push: without a trust region the step would move far
    pushed = x + np.array([0.0, 0.0, 0.0, 25.0])
    free = MpfcSolver(params).solve(pushed, "left", np.zeros(3), 0.1, np.array([0.3, 0]),
                                    [ground])
    held = solver.solve(pushed, "left", np.zeros(3), 0.1, np.array([0.3, 0.0]), [ground])
    assert held.trust_region_active
    assert np.all(np.abs(held.footsteps[0, :2] - first.footsteps[0, :2]) <= 0.1 + 1e-7)
    assert np.max(np.abs(free.footsteps[0, :2] - first.footsteps[0, :2])) > 0.1
    # a new stance starts without a trust region
    after = solver.solve(x, "right", held.footsteps[0], 0.2, np.zeros(2), [ground])
    assert not after.trust_region_active


def test_previous_assignment_is_the_first_incumbent(params, monkeypatch) -> None:
    solver = MpfcSolver(with_params(params, time_limit_ms=10_000.0))
    rng = np.random.default_rng(8)
    inst = random_instance(rng, solver.model, 10)
    first = solve(solver, inst)
    assert first.has_plan
    seen = []
    original = solver.search.run

    def spy(qp, lf, incumbent, deadline):
        seen.append(incumbent)
        return original(qp, lf, incumbent, deadline)

    monkeypatch.setattr(solver.search, "run", spy)
    again = solve(solver, inst, t_remaining_s=inst.t_remaining_s - 0.01)
    local = tuple(int(np.where(solver.last_local.index == i)[0][0])
                  for i in first.foothold_indices)
    assert seen == [local]
    assert again.has_plan


class _FlakySolver:
    """Wraps a piqp.DenseSolver; reports a failure status for the first `fails` solves."""

    def __init__(self, inner, status, fails):
        self.inner, self.status, self.fails = inner, status, fails

    def __getattr__(self, name):
        return getattr(self.inner, name)

    def solve(self):
        if self.fails > 0:
            self.fails -= 1
            self.inner.solve()
            return self.status
        return self.inner.solve()


@pytest.mark.parametrize("status", [piqp.PIQP_MAX_ITER_REACHED, piqp.PIQP_NUMERICS,
                                    piqp.PIQP_UNSOLVED, piqp.PIQP_DUAL_INFEASIBLE])
def test_non_verdict_statuses_are_retried(params, monkeypatch, status) -> None:
    """A QP reported as anything but solved/infeasible is solved again, and the search
    result is still the optimum."""
    good = MpfcSolver(with_params(params, time_limit_ms=10_000.0))
    flaky = MpfcSolver(with_params(params, time_limit_ms=10_000.0))
    real_dense = piqp.DenseSolver
    count = {"n": 0}

    def make():
        count["n"] += 1
        # every third solver instance fails twice before working
        return _FlakySolver(real_dense(), status, 2 if count["n"] % 3 == 1 else 0)

    rng = np.random.default_rng(4)
    inst = random_instance(rng, good.model, 6)
    ref = solve(good, inst)
    monkeypatch.setattr(piqp, "DenseSolver", make)
    got = solve(flaky, inst)
    assert flaky.engine.retries > 0
    assert got.status == ref.status
    if ref.has_plan:
        assert abs(got.objective - ref.objective) <= 1e-6 * max(1.0, abs(ref.objective))


def test_qp_that_never_solves_is_not_called_infeasible(params, monkeypatch) -> None:
    """If piqp keeps failing, the answer is time_limited (unproven), never infeasible."""
    solver = MpfcSolver(params)
    real_dense = piqp.DenseSolver
    monkeypatch.setattr(piqp, "DenseSolver",
                        lambda: _FlakySolver(real_dense(), piqp.PIQP_NUMERICS, 10**6))
    rng = np.random.default_rng(4)
    sol = solve(solver, random_instance(rng, solver.model, 4))
    assert sol.status == "time_limited"


def test_recorded_solves_replay_to_the_same_plans(params) -> None:
    """``MpfcSolver.recorder`` keeps every solve's arguments (the closed-loop benchmark's
    instances); a fresh solver fed them in order makes the same plans."""
    rng = np.random.default_rng(5)
    live = MpfcSolver(params)
    live.recorder = []
    plans = []
    for _ in range(3):
        inst = random_instance(rng, live.model, 8)
        x, t = inst.x_alip.copy(), inst.t_remaining_s
        for _ in range(3):  # warm solves later in the same stance, as the process makes them
            sol = live.solve(x, inst.stance, inst.p_stance, t, inst.vdes, inst.footholds,
                             inst.yaw)
            plans.append(sol.footsteps)
            x, t = live.model.expm_a(0.03) @ x, t - 0.03
    assert len(live.recorder) == 9
    fresh = MpfcSolver(params)
    for inst, plan in zip(live.recorder, plans, strict=True):
        sol = fresh.solve(inst.x_alip, inst.stance, inst.p_stance, inst.t_remaining_s,
                          inst.vdes, inst.footholds, inst.yaw)
        assert (sol.footsteps is None) == (plan is None)
        if plan is not None:
            assert np.allclose(sol.footsteps, plan, atol=1e-9)



@pytest.mark.parametrize("bad", ["x_alip", "p_stance", "vdes", "t_remaining_s"])
def test_a_non_finite_input_is_a_clear_error_at_once(params, bad) -> None:
    """NaN in: a ValueError naming the input, before any search (it used to spend the
    whole time budget on N = 2, or raise LinAlgError in the search on N = 3)."""
    floor = Foothold.from_polygon(np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]]))
    args = {"x_alip": np.zeros(4), "p_stance": np.zeros(3), "t_remaining_s": 0.2,
            "vdes": np.array((0.3, 0.0))}
    args[bad] = float("nan") if bad == "t_remaining_s" else args[bad] * np.nan
    solver = MpfcSolver(params)
    searched = []
    solver.search.run = lambda *a, **k: searched.append(a)  # must not be reached
    with pytest.raises(ValueError, match=bad):
        solver.solve(args["x_alip"], "left", args["p_stance"], args["t_remaining_s"],
                     args["vdes"], [floor])
    assert not searched  # refused before any search (not timed: shared machines are noisy)
