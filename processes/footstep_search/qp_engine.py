"""The piqp QP engine of the exact footstep search: one leaf or relaxation QP at a time.

A footstep planner (the MPFC's (15), the DCM planner's (21)) hands its solve to the search as a
``CondensedQp``: a convex QP in z = [two continuous variables, p_1xy, ..., p_Nxy] with hard
linear rows, optional soft limits and one foothold polygon per footstep. piqp has no
integers: the search (``processes.footstep_search.search``) fixes a foothold per step and asks
this engine for that leaf's QP, with the foothold rows rewritten in place and the soft limits'
slack variables added lazily (see `QpEngine`), which keeps most MPFC QPs at 6 variables.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import piqp

from processes.footstep_search.footholds import LocalFootholds

#: a QP's status (`QpResult.status`)
#: a duality gap this large at piqp's iteration limit is a diverged dual (``QpEngine._run``)
DIVERGED_GAP = 1e8
SOLVED = "solved"
INFEASIBLE = "infeasible"
FAILED = "failed"


#: necessary conditions for a leaf to be feasible, from the footholds' vertices: (ok_first
#: (M,), ok_pair[k] (M, M) for steps k, k+1); a planner's own (``CondensedQp.prefilter``)
Prefilter = Callable[["CondensedQp", LocalFootholds], tuple[np.ndarray, list[np.ndarray]]]


@dataclass
class CondensedQp:
    """One solve's QP in z = [a, b, p_1xy, ..., p_Nxy]: the planner's two continuous
    variables (MPFC: tau = T - T* and the ankle torque u; DCM: sigma_1 and an unused one held
    at 0 by its bounds) and the N footsteps the search assigns footholds to.

    Objective without the soft limits: 0.5 z'Pz + q'z + const. Soft limits: rows
    |Cs z + cs| <= lim penalised by w_soft * violation^2 (none: zero rows). Hard rows:
    Gx z <= hx (MPFC: the crossover rows). Bounds z_lo <= z <= z_hi. The model's states:
    x_n = E[n] z + e[n]. ``prefilter``: the planner's vertex tests that drop leaves before any
    QP (None: none dropped).
    """

    P: np.ndarray
    q: np.ndarray
    const: float
    Cs: np.ndarray
    cs: np.ndarray
    lim: np.ndarray
    w_soft: float
    Gx: np.ndarray
    hx: np.ndarray
    z_lo: np.ndarray
    z_hi: np.ndarray
    E: np.ndarray
    e: np.ndarray
    prefilter: Prefilter | None = None

    def penalty(self, z: np.ndarray) -> float:
        """Soft-limit cost of z: w * sum(max(|x| - lim, 0)^2) over every limited row."""
        viol = np.maximum(np.abs(self.Cs @ z + self.cs) - self.lim, 0.0)
        return float(self.w_soft * viol @ viol)

    def objective(self, z: np.ndarray) -> float:
        """The full objective of z, soft-limit penalty included."""
        return float(0.5 * z @ self.P @ z + self.q @ z + self.const + self.penalty(z))


@dataclass
class QpResult:
    """One QP: status ('solved', 'infeasible', 'failed'), objective of (15a), solution z."""

    status: str
    objective: float
    z: np.ndarray | None


class QpEngine:
    """piqp dense solvers for the leaf and relaxation QPs of one solve.

    Foothold rows are rewritten in place for each assignment, after the QP's hard rows. The
    soft limits enter
    lazily: each QP is solved with slack variables only for the state components in an active
    set A (empty at first); if the solution violates a limit outside A, those components join
    A and the QP is solved again. A QP whose dropped limits are all satisfied is exact,
    because dropping a soft limit only lowers the objective. A persists for the whole solve,
    and one piqp solver is kept per size of A so that dimensions never change under it.
    """

    def __init__(self, n_steps: int, eps_abs: float = 1e-9, eps_rel: float = 1e-10) -> None:
        self.N = n_steps
        self.nz = 2 + 2 * n_steps
        self.eps_abs = eps_abs
        self.eps_rel = eps_rel
        self.K = 0  # foothold rows per step
        self.H = 0  # hard rows (the planner's; fixed per planner)
        self.qp: CondensedQp | None = None
        self.optimizer_s = 0.0
        self.solves = 0
        self.retries = 0
        self.diverged = 0  # solves whose dual diverged at the iteration limit: infeasible
        self._solvers: dict[int, piqp.DenseSolver] = {}
        self.active = np.zeros(0, dtype=int)
        self._form_fresh = True
        #: the first QP of this load solved with no soft limit at all (set by `solve`): the
        #: minimum of (15a) without the soft-limit penalty, for the search's penalty bounds
        self.unpenalised: QpResult | None = None

    # -- per solve ------------------------------------------------------------------------
    def load(self, qp: CondensedQp, k_rows: int) -> None:
        """Take this solve's QP data; foothold slots hold `k_rows` rows per step."""
        k_rows = max(4, k_rows)
        hard = len(qp.hx)
        if k_rows > self.K or hard != self.H:
            self.K = max(self.K, k_rows + (-k_rows) % 4)
            self.H = hard
            rows = hard + self.N * self.K
            self.Gs = np.zeros((rows, self.nz))
            self.hs = np.ones(rows)
            self._solvers.clear()
        self.qp = qp
        n, k, hh = self.N, self.K, self.H
        self.Gs[hh: hh + n * k] = 0.0
        self.hs[hh: hh + n * k] = 1.0
        self.Gs[:hh] = qp.Gx
        self.hs[:hh] = qp.hx
        self._set_active(np.zeros(0, dtype=int))
        self.unpenalised = None

    def _set_active(self, active: np.ndarray) -> None:
        """Build the QP form with slacks for the soft-limit components in `active`."""
        qp = self.qp
        assert qp is not None
        self.active = active
        na, nz, rows_s = len(active), self.nz, self.Gs.shape[0]
        nv = nz + na
        self.P = np.zeros((nv, nv), order="F")
        self.P[:nz, :nz] = qp.P
        self.P[nz:, nz:] = 2.0 * qp.w_soft * np.eye(na)  # w_soft * s's
        self.c = np.zeros(nv)
        self.c[:nz] = qp.q
        self.G = np.zeros((rows_s + 2 * na, nv), order="F")
        self.h = np.ones(rows_s + 2 * na)
        cs = qp.Cs[active]
        self.G[rows_s: rows_s + na, :nz] = cs  # Cs z - s <= lim - cs
        self.G[rows_s + na:, :nz] = -cs  # -Cs z - s <= lim + cs
        self.G[rows_s:, nz:] = np.vstack([-np.eye(na), -np.eye(na)])
        self.h[rows_s: rows_s + na] = qp.lim[active] - qp.cs[active]
        self.h[rows_s + na:] = qp.lim[active] + qp.cs[active]
        self.x_l = np.concatenate([qp.z_lo, np.zeros(na)])
        self.x_u = np.concatenate([qp.z_hi, np.full(na, np.inf)])
        self._form_fresh = True

    def set_rows(self, step: int, f: np.ndarray | None, c: np.ndarray | None) -> None:
        """Write step `step`'s (0-based) foothold rows F p <= c, padded to the solve's row count
        with 0 <= 1 rows (None: only padding). Padding is finite so piqp strips nothing."""
        r0 = self.H + step * self.K
        cols = slice(2 + 2 * step, 4 + 2 * step)
        if f is None:
            self.Gs[r0: r0 + self.K, cols] = 0.0
            self.hs[r0: r0 + self.K] = 1.0
        else:
            kk = f.shape[0]
            self.Gs[r0: r0 + kk, cols] = f
            self.hs[r0: r0 + kk] = c

    # -- solving --------------------------------------------------------------------------
    def solve(self) -> QpResult:
        """Solve with the current rows, growing the active soft-limit set until no dropped
        limit is violated; the objective includes every soft-limit penalty."""
        qp = self.qp
        assert qp is not None
        while True:
            res = self._run()
            if res.status != SOLVED:
                return res
            z = res.z[: self.nz]
            if self.unpenalised is None and len(self.active) == 0:
                self.unpenalised = QpResult(SOLVED, res.objective + qp.const, z)
            viol = qp.Cs @ z
            viol += qp.cs
            np.abs(viol, out=viol)
            viol -= qp.lim
            if len(self.active):
                viol[self.active] = -1.0
            over = viol > 1e-9
            if not over.any():
                # piqp's objective already holds w s'^2 for the active limits, which at the
                # optimum is their penalty; the dropped ones contribute nothing
                res.objective += qp.const
                res.z = z
                return res
            self._set_active(np.union1d(self.active, np.flatnonzero(over)))

    def _settings(self, s: piqp.DenseSolver, attempt: int) -> None:
        """Tolerances of try ``attempt`` (0 first): each retry ten times looser, longer."""
        st = s.settings
        st.verbose = False
        st.eps_abs = self.eps_abs * (10.0 ** attempt)
        st.eps_rel = self.eps_rel * (10.0 ** attempt)
        # the objective carries a large constant that cancels (||e - d||_W), so the duality
        # gap must be tight for the objective to be right to ~1e-10 absolute
        st.eps_duality_gap_abs = 1e-10 * (10.0 ** attempt)
        st.eps_duality_gap_rel = 1e-10 * (10.0 ** attempt)
        st.max_iter = 250 * (attempt + 1)
        st.compute_timings = False

    def _run(self) -> QpResult:
        """One piqp solve; any status but solved/infeasible is retried with a fresh solver and
        looser tolerances, and reported 'failed' if it keeps failing; but a dual that diverged
        at the iteration limit is tried once afresh and then reported 'infeasible' (below)."""
        rows_s = self.Gs.shape[0]
        self.G[:rows_s, : self.nz] = self.Gs
        self.h[:rows_s] = self.hs
        size = len(self.active)
        attempt = 0
        fresh_again = False  # a fresh solver on attempt 0's settings (after a diverged reuse)
        while attempt < 3:
            solver = self._solvers.get(size) if attempt == 0 and not fresh_again else None
            reused = solver is not None
            if solver is None:
                solver = piqp.DenseSolver()
                self._settings(solver, attempt)
                solver.setup(self.P, self.c, None, None, self.G, None, self.h, self.x_l,
                             self.x_u)
                if attempt == 0:  # retries use looser one-off solvers, never cached
                    self._solvers[size] = solver
            elif self._form_fresh:
                solver.update(P=self.P, c=self.c, G=self.G, h_u=self.h, x_l=self.x_l,
                              x_u=self.x_u)
            else:
                solver.update(G=self.G, h_u=self.h)
            self._form_fresh = False
            t0 = time.perf_counter()
            status = solver.solve()
            self.optimizer_s += time.perf_counter() - t0
            self.solves += 1
            if status == piqp.PIQP_SOLVED:
                return QpResult(SOLVED, float(solver.result.info.primal_obj),
                                np.array(solver.result.x))
            if status == piqp.PIQP_PRIMAL_INFEASIBLE:
                return QpResult(INFEASIBLE, np.inf, None)
            self.retries += 1
            self._solvers.pop(size, None)
            self._form_fresh = True
            if (status == piqp.PIQP_MAX_ITER_REACHED
                    and solver.result.info.duality_gap > DIVERGED_GAP):
                # The dual ran off while the primal stalled. A reused solver is tried once
                # afresh (measured: a reused one diverged on a root relaxation a new one
                # solved in 8 iterations); from a fresh one it is a leaf infeasible by a hair
                # (the footholds of two steps, the trust region and the crossover margin
                # missing each other by ~1e-5 m), which piqp cannot certify: retried looser
                # and longer it never converged, and one MPFC solve of a walking run spent
                # 41 ms on 20 such retries. No foot can take it: infeasible.
                if reused:
                    fresh_again = True
                    continue
                self.diverged += 1
                return QpResult(INFEASIBLE, np.inf, None)
            fresh_again = False
            attempt += 1
        return QpResult(FAILED, np.inf, None)
