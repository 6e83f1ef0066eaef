"""Exact mixed-integer search for (15), over the QPs of `processes.footstep_search.qp_engine`.

piqp has no integers, so the foothold assignment is searched here. Each leaf is a QP with
one foothold fixed per step and its constraint hard (no big-M), which is exactly (15) with
those binaries fixed. Two strategies, both exact:

* `enumerate` (N = 2 by default): leaves visited in order of a cheap lower bound, the
  incumbent (the previous solve's assignment) first, stopping once the next bound reaches the
  incumbent. The bound comes from one QP without footholds (value f_b, solution z_b): for
  every feasible z, f(z) >= f_b + 0.5 (z - z_b)' P (z - z_b), because f is convex and its
  gradient at z_b is non-negative along every feasible direction. Minimising the right side
  over T, u (Schur complement S on the footsteps) and over each foothold polygon gives
  per-foothold bounds for all footholds at once (point-polygon distances in the metric S).
  A second, exact bound is computed lazily, once per first-step foothold: the QP with only
  p_1 fixed (later footsteps relaxed to the box around all footholds); it prunes every leaf
  sharing that foothold. Vertex tests drop assignments that cannot meet the crossover or
  trust-region constraints. When a search is not settled after a few QPs, a third bound per
  leaf that sees the soft CoM limits (their penalty's lower bound over the leaf's region,
  added to the quadratic bound around the unpenalised optimum) re-sorts the remaining leaves:
  the quadratic bound has none of the penalty's curvature, so it ranked leaves whose footholds
  push the CoM off its limits (objective 1e4) among the good ones (1e2).
* `branch_and_bound` (longer horizons, when M^N is large): best-first over partial
  assignments, unassigned footsteps relaxed to the bounding box of all footholds (a valid
  relaxation of (20)), children ordered and pre-pruned by the same per-foothold bounds.

The soft CoM limits need slack variables; `QpEngine` (``processes.footstep_search.qp_engine``) adds
them lazily, which keeps most QPs at 6 variables.
"""

from __future__ import annotations

import heapq
import itertools
import math
import time
from dataclasses import dataclass

import numba
import numpy as np

from processes.footstep_search.footholds import LocalFootholds
from processes.footstep_search.qp_engine import (
    FAILED,
    INFEASIBLE,
    SOLVED,
    CondensedQp,
    QpEngine,
    QpResult,
)


@dataclass
class SearchResult:
    """Outcome of one exact search: status 'optimal' | 'time_limited' | 'infeasible'."""

    status: str
    assignment: tuple[int, ...] | None  # indices into the pruned foothold arrays
    z: np.ndarray | None
    objective: float
    nodes: int
    lower_bound: float


class ExactSearch:
    """Global optimum of (15) over foothold assignments; see the module docstring."""

    def __init__(self, engine: QpEngine, rel_tol: float = 1e-8, max_leaves: int = 2000,
                 mode: str = "auto") -> None:
        self.engine = engine
        self.rel_tol = rel_tol
        self.max_leaves = max_leaves
        self.mode = mode
        # how many leading steps get the lazy per-foothold bound: later steps' bounds relax the
        # earlier footsteps to a box and rarely prune
        self.step_bound_depth = 1
        # QPs after which an enumeration adds the soft-limit-aware leaf bounds (~0.3 ms)
        self.penalty_bound_after = 3
        # compile (or load from numba's on-disk cache) the distance kernel now, not mid-solve
        _metric_dist_sq(np.zeros((1, 2)), np.eye(2)[None], np.zeros((1, 3, 2)),
                        np.zeros((1, 3, 2)), np.zeros((1, 4, 2)), np.zeros((1, 4)))
        _penalty_of_leaves(np.zeros(1), np.zeros(1), np.zeros((1, 1, 1)), np.zeros((1, 1, 1)),
                           np.ones(1), 1.0)
        self._chol: np.ndarray | None = None
        self._gamma = 0.0

    def _gap(self, best: float) -> float:
        """Optimality tolerance around the incumbent value (0 while there is none)."""
        if not math.isfinite(best):
            return 0.0
        return self.rel_tol * max(abs(best), 1e-3)

    def _prepare(self, qp: CondensedQp, lf: LocalFootholds) -> None:
        """Load the engine; finite right-hand sides and the padded box rows for this solve."""
        kk = lf.F.shape[1]
        self.engine.load(qp, kk)
        self._c = np.where(np.isfinite(lf.c), lf.c, 1.0)
        self._fbox = np.zeros((kk, 2))
        self._fbox[:4] = [[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0]]
        self._cbox = np.ones(kk)
        self._cbox[:4] = np.concatenate([lf.box_hi, -lf.box_lo])

    def _solve_leaf(self, lf: LocalFootholds, assignment: tuple[int, ...]) -> QpResult:
        for step, i in enumerate(assignment):
            self.engine.set_rows(step, lf.F[i], self._c[i])
        return self.engine.solve()

    def run(
        self,
        qp: CondensedQp,
        lf: LocalFootholds,
        incumbent: tuple[int, ...] | None,
        deadline: float,
    ) -> SearchResult:
        """Search all assignments of the footholds in `lf` to the N steps of `qp`."""
        eng = self.engine
        n, m = eng.N, lf.count
        if m == 0:
            return SearchResult("infeasible", None, None, np.inf, 0, np.inf)
        self._prepare(qp, lf)
        if m == 1:
            return self._single_leaf(lf, n)
        self._metric_factors(qp)
        for step in range(n):
            eng.set_rows(step, None, None)
        nodes = 1
        base = eng.solve()  # (15) without foothold constraints: the root bound
        if base.status == INFEASIBLE:
            return SearchResult("infeasible", None, None, np.inf, nodes, np.inf)
        if base.status == FAILED:
            lb_step = np.zeros((n, m))
            lb_sum = np.zeros((n, m))
            f_b = -np.inf
        else:
            f_b = base.objective
            lb_step, lb_sum = self._foothold_bounds(base.z, lf)
        plain = eng.unpenalised if base.status == SOLVED else None
        ok_first, ok_pairs = self._feasible_masks(qp, lf)
        mode = self.mode
        if mode == "auto":
            mode = "enumerate" if m**n <= self.max_leaves else "branch_and_bound"
        if incumbent is not None and (len(incumbent) != n or max(incumbent) >= m):
            incumbent = None
        if mode == "enumerate":
            pen_bounds = None
            if plain is not None:
                def pen_bounds() -> np.ndarray | None:
                    return self._penalty_leaf_bounds(qp, lf, plain)
            return self._enumerate(lf, f_b, lb_step, lb_sum, ok_first, ok_pairs, incumbent,
                                   deadline, nodes, pen_bounds)
        return self._branch_and_bound(lf, f_b, lb_step, ok_first, ok_pairs, incumbent, deadline,
                                      nodes)

    def _single_leaf(self, lf: LocalFootholds, n: int) -> SearchResult:
        """One foothold (flat ground): (15) has one assignment, so its optimum is that leaf's
        QP. The root relaxation and the bounds could prune nothing: measured live, skipping
        them takes a quarter off a flat-ground solve (one QP instead of two)."""
        a = (0,) * n
        res = self._solve_leaf(lf, a)
        if res.status == SOLVED:
            return self._finish("optimal", a, res.z, res.objective, 1, res.objective)
        if res.status == INFEASIBLE:
            return SearchResult("infeasible", None, None, np.inf, 1, np.inf)
        return self._finish("time_limited", None, None, np.inf, 1, -np.inf)

    # -- bounds -----------------------------------------------------------------------------
    def _metric_factors(self, qp: CondensedQp) -> None:
        """Cholesky factors of the footstep metrics of this solve's Hessian, once per solve:
        ``self._chol`` (2N, 2, 2): the Schur complements S_k of the footstep Hessian S onto
        each step, then the blocks S_kk; ``self._gamma`` with S >= gamma blockdiag(S_kk).
        ``self._chol`` is None when S is not positive definite (then no bound prunes)."""
        n = self.engine.N
        self._chol, self._gamma = None, 0.0
        pm = qp.P
        s_full = pm[2:, 2:] - pm[2:, :2] @ np.linalg.inv(pm[:2, :2]) @ pm[:2, 2:]
        if n == 2:  # the usual case: 2x2 algebra in plain floats (cheaper than numpy calls)
            chol_l, gamma = _bounds_algebra_n2(s_full.tolist())
            if chol_l is None:
                return
            chol = np.array(chol_l)
        else:
            s_full = 0.5 * (s_full + s_full.T)
            mats = np.empty((2 * n, 2, 2))
            for k in range(n):
                kk = slice(2 * k, 2 * k + 2)
                rest = np.r_[0: 2 * k, 2 * k + 2: 2 * n]
                mats[n + k] = s_full[kk, kk]
                mats[k] = s_full[kk, kk]
                if len(rest):
                    mats[k] = mats[k] - s_full[kk, rest] @ np.linalg.solve(
                        s_full[np.ix_(rest, rest)], s_full[rest, kk])
            try:
                chol = np.linalg.cholesky(0.5 * (mats + mats.transpose(0, 2, 1)))
            except np.linalg.LinAlgError:
                return
            tmat = np.zeros_like(s_full)
            for k in range(n):
                tmat[2 * k: 2 * k + 2, 2 * k: 2 * k + 2] = np.linalg.inv(chol[n + k])
            gamma = float(np.linalg.eigvalsh(tmat @ s_full @ tmat.T)[0])
        if np.isfinite(gamma) and np.isfinite(chol).all():
            self._chol, self._gamma = chol, gamma

    def _foothold_bounds(self, z_b: np.ndarray, lf: LocalFootholds
                         ) -> tuple[np.ndarray, np.ndarray]:
        """Per-step, per-foothold bounds on f - f_b, all footholds at once.

        D[k, i] = min over P_i of 0.5 dp' S_k dp (S_k: Schur complement of the footstep
        Hessian S onto step k, dp = p_k - p_k(z_b)); G[k, i] = gamma * the same with the
        block S_kk, where S >= gamma blockdiag(S_kk). A leaf's bound is
        f_b + max(max_k D[k, i_k], sum_k G[k, i_k]). Zero (no pruning) without factors.
        """
        n, m = self.engine.N, lf.count
        if self._chol is None:
            return np.zeros((n, m)), np.zeros((n, m))
        pb = z_b[2:].reshape(n, 2)
        d2 = _metric_dist_sq(np.concatenate([pb, pb]), self._chol, lf.V, lf.Ed, lf.F, lf.c)
        if not np.isfinite(d2).all():
            return np.zeros((n, m)), np.zeros((n, m))
        safety = 0.5 * (1.0 - 1e-7)
        return safety * d2[:n], (safety * max(self._gamma, 0.0)) * d2[n:]

    def _penalty_leaf_bounds(self, qp: CondensedQp, lf: LocalFootholds,
                             plain: QpResult) -> np.ndarray | None:
        """A second bound per leaf, (M,)*N, that sees the soft CoM limits.

        f = f_0 + pen, with f_0 (15a) without the soft limits and pen their penalty. Around
        the minimiser z_0 of f_0 (``plain``), f_0 >= f_0(z_0) + the quadratic foothold bounds
        (as at the root); and over a leaf's region (tau, u in their bounds, p_k in its
        polygon), each row of Cs z + cs lies in an interval found from the polygon vertices,
        so pen >= w * sum of each interval's squared distance outside [-lim, lim]. The two
        bounds add. The root bound sees none of the penalty's curvature, which is what
        makes a leaf whose footholds force the CoM off its limits cost 1e4 where the root
        bound says 1e2."""
        n, m = self.engine.N, lf.count
        lo_t, hi_t = qp.z_lo[:2], qp.z_hi[:2]
        if not (np.all(np.isfinite(lo_t)) and np.all(np.isfinite(hi_t))):
            return None
        cs = qp.Cs
        # tau and u: per row, the extreme values of their part of Cs z
        a = cs[:, :2]
        lo = qp.cs + np.minimum(a * lo_t, a * hi_t).sum(axis=1)
        hi = qp.cs + np.maximum(a * lo_t, a * hi_t).sum(axis=1)
        # each step's footstep: per foothold and row, the extremes over its vertices
        vals = np.stack([lf.V @ cs[:, 2 + 2 * k: 4 + 2 * k].T for k in range(n)])  # (N,M,K,R)
        shape = (m,) * n
        pen = _penalty_of_leaves(lo, hi, vals.min(axis=2), vals.max(axis=2), qp.lim,
                                 qp.w_soft).reshape(shape)
        q_step, q_sum = self._foothold_bounds(plain.z, lf)
        return plain.objective + _leaf_bounds(q_step, q_sum) + (1.0 - 1e-9) * pen

    def _later_step_bounds(self, z: np.ndarray, lf: LocalFootholds) -> np.ndarray | None:
        """Bounds below a node whose first footstep is fixed, from its QP solution z: the same
        quadratic argument as at the root, centred at z, for steps 2..N. Returns (N-1, M) with
        entry [k-1, j] = min over P_j of 0.5 dp' S_k dp, or None without factors."""
        n = self.engine.N
        if self._chol is None or n < 2:
            return None
        pts = z[4:].reshape(n - 1, 2)
        d2 = _metric_dist_sq(pts, self._chol[1:n], lf.V, lf.Ed, lf.F, lf.c)
        if not np.isfinite(d2).all():
            return None
        return (0.5 * (1.0 - 1e-7)) * d2

    def _feasible_masks(
        self, qp: CondensedQp, lf: LocalFootholds
    ) -> tuple[np.ndarray, list[np.ndarray]]:
        """The planner's vertex tests (``CondensedQp.prefilter``), or every leaf kept."""
        if qp.prefilter is not None:
            return qp.prefilter(qp, lf)
        m = lf.count
        return np.ones(m, dtype=bool), [np.ones((m, m), dtype=bool)
                                        for _ in range(self.engine.N - 1)]

    # -- strategies -------------------------------------------------------------------------
    def _enumerate(self, lf, f_b, lb_step, lb_sum, ok_first, ok_pairs, incumbent, deadline,
                   nodes, pen_bounds=None) -> SearchResult:
        """Leaves in order of their lower bound, pruned by the lazy per-step bounds. Once
        ``penalty_bound_after`` QPs have not settled it, ``pen_bounds()`` (the soft-limit-aware
        leaf bounds) raises the remaining leaves' bounds and they are re-sorted: easy solves
        do not pay for it, hard ones stop exploring leaves the CoM limits make expensive."""
        n, m = self.engine.N, lf.count
        shape = (m,) * n
        feasible = np.ones(shape, dtype=bool)
        for k in range(n):
            if k == 0:
                view = [1] * n
                view[0] = m
                feasible &= ok_first.reshape(view)
            else:
                pview = [1] * n
                pview[k - 1] = m
                pview[k] = m
                feasible &= ok_pairs[k - 1].reshape(pview)
        lb = np.where(feasible, f_b + _leaf_bounds(lb_step, lb_sum), np.inf).ravel()
        order = np.argsort(lb, kind="stable")
        pen_at = nodes + self.penalty_bound_after
        best, best_a, best_z = np.inf, None, None
        unresolved = False
        if incumbent is not None:
            res = self._solve_leaf(lf, incumbent)
            nodes += 1
            if res.status == SOLVED:
                best, best_a, best_z = res.objective, incumbent, res.z
            unresolved |= res.status == FAILED
        inc_flat = None if incumbent is None else int(np.ravel_multi_index(incumbent, shape))
        # step_lb[k][i]: exact QP value with only step k fixed to foothold i (the others relaxed
        # to the box around all footholds); computed lazily, shared by the M^(N-1) leaves using
        # it. Only the first `step_bound_depth` steps get one: later steps' bounds relax the
        # earlier footsteps to a box and rarely prune.
        depth = min(self.step_bound_depth, n)
        step_lb: list[list[float | None]] = [[None] * m for _ in range(depth)]
        # below[i]: quadratic bounds for steps 2..N under the node "p_1 in P_i", from its QP
        below: list[np.ndarray | None] = [None] * m
        cutoff = best - self._gap(best)
        proven_lb = np.inf
        pos = 0
        while pos < len(order):
            if pen_bounds is not None and nodes >= pen_at:
                extra = pen_bounds()
                pen_bounds = None
                if extra is not None:
                    lb = np.maximum(lb, extra.ravel())
                    rest = order[pos:]
                    order = np.concatenate([order[:pos],
                                            rest[np.argsort(lb[rest], kind="stable")]])
            flat = int(order[pos])
            bound = float(lb[flat])
            pos += 1
            if bound == np.inf or bound >= cutoff:
                proven_lb = bound
                break
            if flat == inc_flat:
                continue
            if time.perf_counter() > deadline:
                return self._finish("time_limited", best_a, best_z, best, nodes, float(bound))
            a = _unravel(flat, m, n)
            if best < np.inf:
                pruned = False
                for k in range(depth):
                    val = step_lb[k][a[k]]
                    if val is None:
                        val, z_node = self._step_bound(lf, k, a[k])
                        step_lb[k][a[k]] = val
                        nodes += 1
                        if k == 0 and z_node is not None:
                            below[a[0]] = self._later_step_bounds(z_node, lf)
                    if val >= cutoff:
                        pruned = True
                        break
                if pruned:
                    continue
                extra = below[a[0]]
                if extra is not None and n > 1:
                    gain = max(extra[k - 1, a[k]] for k in range(1, n))
                    if step_lb[0][a[0]] + gain >= cutoff:
                        continue
            res = self._solve_leaf(lf, a)
            nodes += 1
            if res.status == SOLVED and res.objective < best:
                best, best_a, best_z = res.objective, a, res.z
                cutoff = best - self._gap(best)
            unresolved |= res.status == FAILED
        status = "optimal"
        if unresolved:
            status = "time_limited"
        if best_a is None and not unresolved:
            status = "infeasible"
        return self._finish(status, best_a, best_z, best, nodes, min(proven_lb, best))

    def _step_bound(
        self, lf: LocalFootholds, step: int, i: int
    ) -> tuple[float, np.ndarray | None]:
        """Lower bound for every leaf with foothold i at `step`: the QP with that step fixed
        and the others relaxed to the box around all footholds (+inf if infeasible; -inf if
        the QP could not be solved, which proves nothing), and its solution."""
        eng = self.engine
        for k in range(eng.N):
            if k == step:
                eng.set_rows(k, lf.F[i], self._c[i])
            else:
                eng.set_rows(k, self._fbox, self._cbox)
        res = eng.solve()
        if res.status == SOLVED:
            return res.objective, res.z
        return (np.inf if res.status == INFEASIBLE else -np.inf), None

    def _branch_and_bound(self, lf, f_b, lb_step, ok_first, ok_pairs, incumbent, deadline,
                          nodes) -> SearchResult:
        eng = self.engine
        n = eng.N
        best, best_a, best_z = np.inf, None, None
        unresolved = False
        seeds = []
        if incumbent is not None:
            seeds.append(tuple(incumbent))
        greedy = tuple(int(np.argmin(lb_step[k])) for k in range(n))
        if greedy not in seeds:
            seeds.append(greedy)
        for a in seeds:
            res = self._solve_leaf(lf, a)
            nodes += 1
            if res.status == SOLVED and res.objective < best:
                best, best_a, best_z = res.objective, a, res.z
            unresolved |= res.status == FAILED
        counter = itertools.count()
        heap: list[tuple[float, int, tuple[int, ...]]] = [(f_b, next(counter), ())]
        seen = set(seeds)
        while heap:
            bound, _, prefix = heapq.heappop(heap)
            if bound >= best - self._gap(best):
                heap.clear()
                break
            if time.perf_counter() > deadline:
                return self._finish("time_limited", best_a, best_z, best, nodes, bound)
            k = len(prefix)
            for step, i in enumerate(prefix):
                eng.set_rows(step, lf.F[i], self._c[i])
            for step in range(k + 1, n):
                eng.set_rows(step, self._fbox, self._cbox)
            for i in np.argsort(lb_step[k]):
                i = int(i)
                if not (ok_first[i] if k == 0 else ok_pairs[k - 1][prefix[-1], i]):
                    continue
                child_lb = max(bound, f_b + lb_step[k, i])
                if child_lb >= best - self._gap(best):
                    continue
                child = (*prefix, i)
                if len(child) == n and child in seen:
                    continue
                eng.set_rows(k, lf.F[i], self._c[i])
                res = eng.solve()
                nodes += 1
                if res.status == FAILED:
                    unresolved = True
                    continue
                if res.status != SOLVED:
                    continue
                if len(child) == n:
                    if res.objective < best:
                        best, best_a, best_z = res.objective, child, res.z
                elif res.objective < best - self._gap(best):
                    heapq.heappush(heap, (max(res.objective, child_lb), next(counter), child))
        status = "optimal"
        if unresolved:
            status = "time_limited"
        if best_a is None and not unresolved:
            status = "infeasible"
        return self._finish(status, best_a, best_z, best, nodes, best)

    @staticmethod
    def _finish(status, best_a, best_z, best, nodes, lower) -> SearchResult:
        return SearchResult(status, best_a, best_z, float(best), nodes, float(lower))


def _leaf_bounds(lb_step: np.ndarray, lb_sum: np.ndarray) -> np.ndarray:
    """(M,)*N quadratic bounds on f - f_b of every leaf from the per-step, per-foothold
    bounds of ``_foothold_bounds``: max(max_k D[k, i_k], sum_k G[k, i_k])."""
    n, m = lb_step.shape
    shape = (m,) * n
    lb_max = np.zeros(shape)
    lb_add = np.zeros(shape)
    for k in range(n):
        view = [1] * n
        view[k] = m
        lb_max = np.maximum(lb_max, lb_step[k].reshape(view))
        lb_add = lb_add + lb_sum[k].reshape(view)
    return np.maximum(lb_max, lb_add)


@numba.njit(cache=True, nogil=True)
def _metric_dist_sq(points: np.ndarray, chol: np.ndarray, verts: np.ndarray,
                    edges: np.ndarray, f: np.ndarray, c: np.ndarray) -> np.ndarray:
    """(P, M) squared distance from each point to each foothold polygon in the point's metric
    S = L L' (``chol[p]`` = L): min over the polygon of (x - p)' S (x - p), zero inside.

    Mapping by L' turns the metric distance into the Euclidean one, so it is the distance to
    the nearest boundary segment after mapping (a polygon is convex: outside, the nearest
    point is on the boundary). ``f``/``c`` are the polygons' half-planes (padded rows
    0 <= inf); ``verts``/``edges`` padded as ``LocalFootholds`` pads them."""
    n_p, m, kv = points.shape[0], verts.shape[0], verts.shape[1]
    out = np.empty((n_p, m))
    for a in range(n_p):
        px, py = points[a, 0], points[a, 1]
        l00, l01, l10, l11 = chol[a, 0, 0], chol[a, 0, 1], chol[a, 1, 0], chol[a, 1, 1]
        qx, qy = px * l00 + py * l10, px * l01 + py * l11  # p' L
        for i in range(m):
            inside = True
            for r in range(f.shape[1]):
                if f[i, r, 0] * px + f[i, r, 1] * py > c[i, r] + 1e-12:
                    inside = False
                    break
            if inside:
                out[a, i] = 0.0
                continue
            best = np.inf
            for k in range(kv):
                vx, vy = verts[i, k, 0], verts[i, k, 1]
                ex, ey = edges[i, k, 0], edges[i, k, 1]
                wx = qx - (vx * l00 + vy * l10)
                wy = qy - (vx * l01 + vy * l11)
                mx, my = ex * l00 + ey * l10, ex * l01 + ey * l11
                ee = mx * mx + my * my
                if ee > 0.0:
                    t = (wx * mx + wy * my) / ee
                    t = min(max(t, 0.0), 1.0)
                    wx -= t * mx
                    wy -= t * my
                d = wx * wx + wy * wy
                if d < best:
                    best = d
            out[a, i] = best
    return out


@numba.njit(cache=True, nogil=True)
def _penalty_of_leaves(lo0: np.ndarray, hi0: np.ndarray, lo_k: np.ndarray, hi_k: np.ndarray,
                       lim: np.ndarray, w: float) -> np.ndarray:
    """Lower bound of the soft-limit penalty of every leaf, flat in row-major order (step 1
    slowest): each row's interval is the sum of the tau/u part [lo0, hi0] and each step's
    foothold part [lo_k[k, i_k], hi_k[k, i_k]]; its squared distance outside [-lim, lim]."""
    n, m, r = lo_k.shape
    total = m**n
    out = np.empty(total)
    for flat in range(total):
        acc = 0.0
        for row in range(r):
            lo, hi, rem = lo0[row], hi0[row], flat
            for k in range(n - 1, -1, -1):
                i = rem % m
                rem //= m
                lo += lo_k[k, i, row]
                hi += hi_k[k, i, row]
            d = max(lo - lim[row], -lim[row] - hi, 0.0)
            acc += d * d
        out[flat] = w * acc
    return out


def _bounds_algebra_n2(
    s: list[list[float]],
) -> tuple[list[list[list[float]]] | None, float]:
    """For N = 2 and the 4x4 footstep Hessian S (nested lists): Cholesky factors of the two
    Schur complements S_1, S_2 and of the blocks S_11, S_22, and gamma = lambda_min of
    blockdiag(L_kk^-1) S blockdiag(L_kk^-T). Returns (None, 0) if S is not positive definite."""

    def blk(i: int, j: int) -> tuple[float, float, float, float]:
        return s[i][j], s[i][j + 1], s[i + 1][j], s[i + 1][j + 1]

    def inv(a: tuple[float, float, float, float]) -> tuple[float, float, float, float]:
        det = a[0] * a[3] - a[1] * a[2]
        return a[3] / det, -a[1] / det, -a[2] / det, a[0] / det

    def mul(a, b):  # 2x2 products, row-major tuples
        return (a[0] * b[0] + a[1] * b[2], a[0] * b[1] + a[1] * b[3],
                a[2] * b[0] + a[3] * b[2], a[2] * b[1] + a[3] * b[3])

    def chol(a):
        if a[0] <= 0.0:
            return None
        l11 = math.sqrt(a[0])
        l21 = 0.5 * (a[1] + a[2]) / l11
        d = a[3] - l21 * l21
        if d <= 0.0:
            return None
        return l11, l21, math.sqrt(d)

    s11, s12, s21, s22 = blk(0, 0), blk(0, 2), blk(2, 0), blk(2, 2)
    try:
        t1 = mul(mul(s12, inv(s22)), s21)
        t2 = mul(mul(s21, inv(s11)), s12)
    except ZeroDivisionError:
        return None, 0.0
    mats = [tuple(x - y for x, y in zip(s11, t1, strict=True)),
            tuple(x - y for x, y in zip(s22, t2, strict=True)), s11, s22]
    factors = [chol(a) for a in mats]
    if any(f is None for f in factors):
        return None, 0.0
    out = [[[f[0], 0.0], [f[1], f[2]]] for f in factors]
    # T S T' = [[I, X], [X', I]] with X = L_11^-1 S_12 L_22^-T, whose eigenvalues are
    # 1 -+ singular values of X: gamma = 1 - sigma_max(X), in closed form for 2x2 X
    f1, f2 = factors[2], factors[3]
    li1 = (1.0 / f1[0], 0.0, -f1[1] / (f1[0] * f1[2]), 1.0 / f1[2])
    li2t = (1.0 / f2[0], -f2[1] / (f2[0] * f2[2]), 0.0, 1.0 / f2[2])
    x = mul(mul(li1, s12), li2t)
    fro = x[0] ** 2 + x[1] ** 2 + x[2] ** 2 + x[3] ** 2
    det = x[0] * x[3] - x[1] * x[2]
    smax = math.sqrt(max(0.5 * (fro + math.sqrt(max(fro * fro - 4.0 * det * det, 0.0))), 0.0))
    gamma = 1.0 - smax
    return out, gamma


def _unravel(flat: int, m: int, n: int) -> tuple[int, ...]:
    """Row-major index `flat` of an (m,)*n array as a tuple (step 1 first)."""
    out = [0] * n
    for k in range(n - 1, -1, -1):
        flat, out[k] = divmod(flat, m)
    return tuple(out)
