"""The exact search returns the global optimum of (15): it matches an exhaustive enumeration
of every foothold assignment, each solved in the paper's literal big-M form, to 1e-6."""

from __future__ import annotations

import numpy as np
import pytest
from mpfc_test_helpers import (
    exhaustive_search,
    rel_err,
    solve,
    solve_exactly,
    with_params,
)

from processes.mpfc import MpfcSolver
from processes.mpfc.problem import MpfcModel, build_miqp
from tools.testbed.gurobi_reference import GurobiBackend, gurobi_available
from tools.testbed.mpfc_instances import random_instance

FOOTHOLD_COUNTS = [1, 2, 3, 4, 6, 8, 11, 14, 17, 20]
SLOW_OK = 10_000.0  # ms: these tests are about the optimum, not the wall clock of a busy box


@pytest.mark.parametrize("m", FOOTHOLD_COUNTS)
def test_enumeration_matches_exhaustive_reference(params, m) -> None:
    solver = MpfcSolver(with_params(params, time_limit_ms=SLOW_OK))
    rng = np.random.default_rng(100 + m)
    for _ in range(3):
        inst = random_instance(rng, solver.model, m)
        solver.reset()
        sol = solve_exactly(solver, inst)
        if sol.has_plan:
            # the plan really lies in the chosen footholds
            for k, i in enumerate(sol.foothold_indices):
                assert inst.footholds[i].contains(sol.footsteps[k], tol=1e-6)


@pytest.mark.parametrize("m", [2, 5, 9, 20])
def test_branch_and_bound_matches_exhaustive_reference(params, m) -> None:
    solver = MpfcSolver(with_params(params, search="branch_and_bound", time_limit_ms=SLOW_OK))
    rng = np.random.default_rng(200 + m)
    for _ in range(2):
        inst = random_instance(rng, solver.model, m)
        solve_exactly(solver, inst)


@pytest.mark.parametrize("search", ["enumerate", "branch_and_bound"])
def test_longer_horizon_is_exact_too(params, search) -> None:
    """N = 3 (M^3 leaves): both strategies agree with the exhaustive reference."""
    solver = MpfcSolver(with_params(params, horizon_steps=3, search=search,
                                     time_limit_ms=SLOW_OK))
    rng = np.random.default_rng(7)
    for m in (2, 4):
        inst = random_instance(rng, solver.model, m)
        solve_exactly(solver, inst)


def test_consecutive_solves_with_incumbent_and_trust_region_stay_exact(params) -> None:
    """Within one stance, T* shrinks; the previous assignment seeds the search and the trust
    region binds p_1: each solve still equals the reference of the same problem."""
    solver = MpfcSolver(with_params(params, time_limit_ms=SLOW_OK))
    rng = np.random.default_rng(11)
    checked_trust = 0
    for _ in range(4):
        inst = random_instance(rng, solver.model, 10)
        solver.reset()
        t0 = 0.36
        for k in range(5):
            t = t0 - 0.06 * k
            sol = solve_exactly(solver, inst, k, t_remaining_s=t)
            checked_trust += sol.trust_region_active
    assert checked_trust > 0


def test_simulation_parameters_are_exact_too(params) -> None:
    """Table V's simulation column (much larger state costs) is solved exactly as well."""
    from pathlib import Path

    from processes.mpfc import MpfcParams
    from runtime.params import load

    yaml = Path(__file__).resolve().parents[2] / "hw_config" / "gains" / "mpfc.yaml"
    solver = MpfcSolver(with_params(load(MpfcParams, yaml, "simulation"),
                                    time_limit_ms=SLOW_OK))
    rng = np.random.default_rng(5)
    for m in (3, 12):
        inst = random_instance(rng, solver.model, m)
        solve_exactly(solver, inst)


@pytest.mark.skipif(not gurobi_available(), reason="gurobipy not installed or unlicensed")
@pytest.mark.parametrize("m", [1, 4, 10, 20])
def test_gurobi_agrees_with_the_search(params, m) -> None:
    """The optional Gurobi backend, with tight tolerances, finds the same optimum."""
    solver = MpfcSolver(with_params(params, time_limit_ms=SLOW_OK))
    backend = GurobiBackend()
    rng = np.random.default_rng(300 + m)
    for _ in range(3):
        inst = random_instance(rng, solver.model, m)
        solver.reset()
        sol = solve(solver, inst)
        g = backend.solve(build_miqp(MpfcModel(params), solver.last_inputs, solver.last_local))
        if g.status == "infeasible":
            assert sol.status == "infeasible"
            continue
        assert g.status == "optimal" and sol.status == "optimal"
        assert rel_err(sol.objective, g.objective) <= 1e-6, (sol.objective, g.objective)


def test_both_strategies_agree_on_a_stream_of_warm_solves(params) -> None:
    """Enumeration (with the solver's state: incumbents, trust regions) and a stateless
    branch and bound agree on every solve of a walking-like stream, infeasible ones too."""
    import time

    from processes.footstep_search.qp_engine import QpEngine
    from processes.footstep_search.search import ExactSearch

    solver = MpfcSolver(with_params(params, time_limit_ms=SLOW_OK))
    bb = ExactSearch(QpEngine(params.horizon_steps), params.optimality_rel_tol,
                     params.enumerate_max_leaves, "branch_and_bound")
    rng = np.random.default_rng(0)
    seen = set()
    for _ in range(25):
        inst = random_instance(rng, solver.model, int(rng.integers(1, 21)))
        solver.reset()
        x, t = inst.x_alip.copy(), inst.t_remaining_s
        for _ in range(4):
            sol = solve(solver, inst, x_alip=x, t_remaining_s=t)
            qp = solver.model.condense(solver.last_inputs)
            r = bb.run(qp, solver.last_local, None, time.perf_counter() + 100.0)
            seen.add(sol.status)
            assert r.status == sol.status
            if sol.status == "optimal":
                assert rel_err(r.objective, sol.objective) <= 1e-6
            if t <= 0.03:
                break
            x = solver.model.expm_a(0.03) @ x + rng.normal(0, 1, 4) * [0.003, 0.003, 0.3, 0.3]
            t -= 0.03
    assert seen == {"optimal", "infeasible"}


def test_one_foothold_is_solved_as_its_one_qp(params) -> None:
    """Flat ground has one foothold, so (15) has one assignment: the search solves that one
    QP (no root relaxation) and still equals the reference, with and without the trust
    region of a later solve in the same stance."""
    solver = MpfcSolver(with_params(params, time_limit_ms=SLOW_OK))
    rng = np.random.default_rng(31)
    for _ in range(4):
        inst = random_instance(rng, solver.model, 1)
        solver.reset()
        for t in (0.36, 0.2):
            sol = solve_exactly(solver, inst, t_remaining_s=t)
            assert sol.nodes_explored == 1
            if sol.has_plan:
                assert sol.foothold_indices == (0,) * solver.params.horizon_steps


@pytest.mark.parametrize("horizon", [2, 3])
def test_the_bounds_prune_no_leaf_better_than_the_answer(params, horizon) -> None:
    """Against every leaf QP of the search's own condensed form (no bound trusted), the
    search's answer is the best leaf, infeasible when every leaf is."""
    from processes.footstep_search.qp_engine import QpEngine
    from processes.footstep_search.search import ExactSearch

    solver = MpfcSolver(with_params(params, horizon_steps=horizon, time_limit_ms=SLOW_OK))
    every = ExactSearch(QpEngine(horizon), params.optimality_rel_tol)
    rng = np.random.default_rng(40 + horizon)
    for m in (2, 5, 9) if horizon == 2 else (2, 4):
        inst = random_instance(rng, solver.model, m)
        sol = solve(solver, inst)
        qp = solver.model.condense(solver.last_inputs)
        ref = exhaustive_search(every, qp, solver.last_local)
        assert ref.nodes == solver.last_local.count ** horizon
        assert ref.status == sol.status, (ref.status, sol.status)
        if sol.status == "optimal":
            assert rel_err(sol.objective, ref.objective) <= 1e-6, (sol.objective, ref.objective)
