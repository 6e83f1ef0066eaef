"""Optional Gurobi backend: solves the literal big-M MIQP (15)-(20), as the paper did.

Gurobi's default MIP gap and integer tolerance let the big-M rows leak (its objective sat up
to 3e-4 below the true optimum here), so every tolerance is tightened: MIPGap 0, IntFeasTol,
FeasibilityTol and OptimalityTol 1e-9. Single-threaded, like the piqp search.
"""

from __future__ import annotations

import itertools
import time
from dataclasses import dataclass

import numpy as np

from processes.footstep_search.miqp import MiqpData

try:  # gurobipy is optional
    import gurobipy as gp
    from gurobipy import GRB
except ImportError:  # pragma: no cover - depends on the environment
    gp = None
    GRB = None


def gurobi_available() -> bool:
    """True when gurobipy imports and a licence (the size-limited one is enough) works."""
    if gp is None:
        return False
    try:
        with gp.Env(params={"OutputFlag": 0}) as env, gp.Model(env=env) as m:
            m.addVar()
            m.optimize()
        return True
    except gp.GurobiError:
        return False


@dataclass
class GurobiResult:
    """Status ('optimal', 'time_limited', 'infeasible'), objective of (15a), the continuous
    solution v, the chosen foothold per step, Gurobi's runtime and wall time, B&B nodes."""

    status: str
    objective: float
    v: np.ndarray | None
    assignment: tuple[int, ...] | None
    runtime_ms: float
    wall_ms: float
    nodes: int


class GurobiBackend:
    """Builds and solves one gurobipy model per call (the instances differ in size)."""

    def __init__(self, time_limit_s: float = 10.0, threads: int = 1) -> None:
        if gp is None:
            raise ImportError("gurobipy is not installed: pip install gurobipy")
        self.env = gp.Env(params={"OutputFlag": 0})
        self.time_limit_s = time_limit_s
        self.threads = threads

    def solve(self, d: MiqpData) -> GurobiResult:
        """Solve the MIQP `d` to global optimality (zero gap, 1e-9 tolerances)."""
        t0 = time.perf_counter()
        with gp.Model(env=self.env) as m:
            m.Params.MIPGap = 0.0
            m.Params.MIPGapAbs = 0.0
            m.Params.IntFeasTol = 1e-9
            m.Params.FeasibilityTol = 1e-9
            m.Params.OptimalityTol = 1e-9
            m.Params.Threads = self.threads
            m.Params.TimeLimit = self.time_limit_s
            nv = d.P.shape[0]
            x = m.addMVar(nv, lb=d.lb, ub=d.ub, name="v")
            mu = m.addMVar(d.N * d.M, vtype=GRB.BINARY, name="mu")
            m.setObjective(0.5 * (x @ d.P @ x) + d.q @ x + d.const, GRB.MINIMIZE)
            m.addConstr(d.Aeq @ x == d.beq)
            m.addConstr(d.G @ x + d.Gmu @ mu <= d.h)
            m.addConstr(d.Smu @ mu == 1.0)
            m.optimize()
            wall = (time.perf_counter() - t0) * 1e3
            runtime = m.Runtime * 1e3
            nodes = int(m.NodeCount)
            if m.Status == GRB.INFEASIBLE or (m.Status == GRB.INF_OR_UNBD):
                return GurobiResult("infeasible", np.inf, None, None, runtime, wall, nodes)
            if m.SolCount == 0:
                return GurobiResult("time_limited", np.inf, None, None, runtime, wall, nodes)
            mu_v = np.asarray(mu.X).reshape(d.N, d.M)
            status = "optimal" if m.Status == GRB.OPTIMAL else "time_limited"
            return GurobiResult(status, float(m.ObjVal), np.asarray(x.X),
                                tuple(int(i) for i in mu_v.argmax(axis=1)), runtime, wall, nodes)


def solve_fixed_assignment(d: MiqpData, assignment: tuple[int, ...]) -> tuple[str, float]:
    """Reference: the MIQP with its binaries fixed, solved with piqp in its literal form
    (explicit states, 3D footsteps, slacks, relaxed big-M rows kept). Returns (status, obj)."""
    import piqp

    g, h = d.fixed(assignment)
    # tight duality gap first (the objective is a difference of large terms), looser on a
    # failure; anything but solved/infeasible is retried, never taken as a verdict
    for gap_abs, gap_rel in ((1e-11, 1e-12), (1e-10, 1e-10), (1e-9, 1e-9)):
        s = piqp.DenseSolver()
        s.settings.verbose = False
        s.settings.eps_abs = 1e-10
        s.settings.eps_rel = 1e-11
        s.settings.eps_duality_gap_abs = gap_abs
        s.settings.eps_duality_gap_rel = gap_rel
        s.settings.max_iter = 1000
        s.setup(np.asfortranarray(d.P), d.q, np.asfortranarray(d.Aeq), d.beq,
                np.asfortranarray(g), None, h, d.lb, d.ub)
        status = s.solve()
        if status == piqp.PIQP_SOLVED:
            return "solved", float(s.result.info.primal_obj) + d.const
        if status == piqp.PIQP_PRIMAL_INFEASIBLE:
            return "infeasible", np.inf
    return "failed", np.nan


def exhaustive_reference(d: MiqpData) -> tuple[float, tuple[int, ...] | None, int]:
    """Reference optimum: every one of the M^N assignments solved in the literal form.
    Returns (best objective, its assignment, number of QPs that failed to solve)."""
    best, best_a, failed = np.inf, None, 0
    for a in itertools.product(range(d.M), repeat=d.N):
        status, obj = solve_fixed_assignment(d, a)
        failed += status == "failed"
        if status == "solved" and obj < best:
            best, best_a = obj, a
    return best, best_a, failed


def gurobi_wanted(skip: bool) -> bool:
    """A benchmark's Gurobi comparison: on unless ``skip`` (``--no-gurobi``) or gurobipy is
    not there (said on stderr, so a figure's absence has a reason)."""
    if skip:
        return False
    if not gurobi_available():
        import sys

        print("gurobipy not installed (or no licence): Gurobi comparison skipped",
              file=sys.stderr)
        return False
    return True
