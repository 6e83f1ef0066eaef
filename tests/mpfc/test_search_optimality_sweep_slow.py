"""Longer sweep (slow): 5 instances for every foothold count 1..20, warm and cold, against the
exhaustive literal-form reference and, when installed, Gurobi."""

from __future__ import annotations

import numpy as np
import pytest
from mpfc_test_helpers import objective_matches, reference, rel_err, solve, with_params

from processes.mpfc import MpfcSolver
from processes.mpfc.problem import build_miqp
from tools.testbed.gurobi_reference import GurobiBackend, gurobi_available
from tools.testbed.mpfc_instances import random_instance


@pytest.mark.slow
@pytest.mark.parametrize("m", list(range(1, 21)))
def test_sweep_every_foothold_count(params, m) -> None:
    solver = MpfcSolver(with_params(params, time_limit_ms=10_000.0))
    backend = GurobiBackend() if gurobi_available() else None
    rng = np.random.default_rng(1000 + m)
    for _ in range(5):
        inst = random_instance(rng, solver.model, m)
        solver.reset()
        for t in (inst.t_remaining_s, inst.t_remaining_s - 0.05):
            sol = solve(solver, inst, t_remaining_s=t)
            ref, _ = reference(solver)
            assert objective_matches(sol, ref), (m, sol.status, sol.objective, ref)
            if backend is not None:
                g = backend.solve(build_miqp(solver.model, solver.last_inputs,
                                             solver.last_local))
                if np.isfinite(ref):
                    assert rel_err(g.objective, ref) <= 1e-6
                else:
                    assert g.status == "infeasible"
