"""The soft-limit-aware leaf bounds of the exact search: never above a leaf's true optimum, and
much tighter than the root bound where footholds push the CoM past its soft limits."""

from __future__ import annotations

import itertools

import numpy as np
from mpfc_test_helpers import solve, solve_exactly, with_params

from processes.footstep_search.qp_engine import SOLVED
from processes.mpfc import MpfcSolver
from tools.testbed.mpfc_instances import random_instance

SLOW_OK = 10_000.0


def _instances_with_binding_limits(solver, count, seed):
    """Generated instances whose unconstrained solve already needs the soft limits."""
    rng = np.random.default_rng(seed)
    found = []
    while len(found) < count:
        inst = random_instance(rng, solver.model, int(rng.integers(4, 10)))
        solver.reset()
        solve(solver, inst)
        if solver.engine.unpenalised is not None and len(solver.engine.active):
            found.append(inst)
    return found


def test_penalty_bounds_never_exceed_a_leaf_optimum(params):
    solver = MpfcSolver(with_params(params, time_limit_ms=SLOW_OK))
    search, eng = solver.search, solver.engine
    tighter = 0
    for inst in _instances_with_binding_limits(solver, 4, seed=11):
        solver.reset()
        solve(solver, inst)
        qp, lf = solver.model.condense(solver.last_inputs), solver.last_local
        search._prepare(qp, lf)
        base = eng.solve()
        assert base.status == SOLVED
        bounds = search._penalty_leaf_bounds(qp, lf, eng.unpenalised)
        assert bounds is not None and bounds.shape == (lf.count,) * eng.N
        for a in itertools.product(range(lf.count), repeat=eng.N):
            leaf = search._solve_leaf(lf, a)
            if leaf.status != SOLVED:
                continue
            assert bounds[a] <= leaf.objective + 1e-7 * max(abs(leaf.objective), 1.0), (
                a, bounds[a], leaf.objective)
            tighter += bounds[a] > base.objective + 10.0
    assert tighter > 0  # the bound does more than restate the root objective


def test_search_with_the_penalty_bounds_from_the_start_stays_exact(params):
    solver = MpfcSolver(with_params(params, time_limit_ms=SLOW_OK))
    solver.search.penalty_bound_after = 0
    rng = np.random.default_rng(12)
    for m in (3, 7, 12, 18):
        inst = random_instance(rng, solver.model, m)
        solver.reset()
        solve_exactly(solver, inst, m)
