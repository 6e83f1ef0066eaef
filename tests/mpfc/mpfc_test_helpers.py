"""Test helpers: run the solver on a generated instance and compute the reference optimum."""

from __future__ import annotations

import dataclasses
import itertools

import numpy as np

from processes.footstep_search.footholds import LocalFootholds
from processes.footstep_search.qp_engine import SOLVED, CondensedQp
from processes.footstep_search.search import ExactSearch, SearchResult
from processes.mpfc import MpfcParams, MpfcSolution, MpfcSolver
from processes.mpfc.problem import build_miqp
from processes.mpfc.solver import Instance
from runtime.params import check
from tools.testbed.gurobi_reference import exhaustive_reference


def solve(solver: MpfcSolver, inst: Instance, **over) -> MpfcSolution:
    """Call the public API with the instance's arguments (overridable)."""
    args = dict(x_alip=inst.x_alip, stance=inst.stance, p_stance=inst.p_stance,
                t_remaining_s=inst.t_remaining_s, vdes=inst.vdes, footholds=inst.footholds,
                yaw=inst.yaw)
    args.update(over)
    return solver.solve(**args)


def reference(solver: MpfcSolver) -> tuple[float, tuple[int, ...] | None]:
    """Exhaustive optimum of the solver's last problem in the literal big-M form (15)-(20),
    with the assignment mapped to indices of the caller's foothold list."""
    d = build_miqp(solver.model, solver.last_inputs, solver.last_local)
    best, a, failed = exhaustive_reference(d)
    assert failed == 0
    if a is None:
        return best, None
    return best, tuple(int(solver.last_local.index[i]) for i in a)


def rel_err(a: float, b: float) -> float:
    """Relative difference; objectives below 1 are compared absolutely (the objective is a
    difference of large terms, so its absolute accuracy is what a QP can give)."""
    return abs(a - b) / max(abs(a), abs(b), 1.0)


def with_params(params: MpfcParams, **changes) -> MpfcParams:
    """A validated copy of params with some fields changed."""
    return check(dataclasses.replace(params, **changes))


def objective_matches(sol: MpfcSolution, ref: float, tol: float = 1e-6) -> bool:
    """The search's verdict agrees with the reference (both infeasible, or equal values)."""
    if not np.isfinite(ref):
        return sol.status == "infeasible"
    return sol.status == "optimal" and rel_err(sol.objective, ref) <= tol


def solve_exactly(solver: MpfcSolver, inst: Instance, *note: object, **over) -> MpfcSolution:
    """``solve``, asserting that its verdict is the exhaustive ``reference``'s of the same
    problem (``note``: what the failure says first, besides the two verdicts)."""
    sol = solve(solver, inst, **over)
    ref, _ = reference(solver)
    assert objective_matches(sol, ref), (*note, sol.status, sol.objective, ref)
    return sol


def exhaustive_search(search: ExactSearch, qp: CondensedQp, lf: LocalFootholds) -> SearchResult:
    """Reference in the search's own condensed form: every assignment's leaf QP (M^N of them)
    solved with the search's engine and the best kept, so no bound or pruning is trusted."""
    n, m = search.engine.N, lf.count
    if m == 0:
        return SearchResult("infeasible", None, None, np.inf, 0, np.inf)
    search._prepare(qp, lf)
    best, best_a, best_z, nodes = np.inf, None, None, 0
    for a in itertools.product(range(m), repeat=n):
        res = search._solve_leaf(lf, a)
        nodes += 1
        if res.status == SOLVED and res.objective < best:
            best, best_a, best_z = res.objective, a, res.z
    status = "optimal" if best_a is not None else "infeasible"
    return SearchResult(status, best_a, best_z, float(best), nodes, float(best))
