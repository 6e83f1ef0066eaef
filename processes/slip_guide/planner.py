"""The SLIP foothold selector: Problem 2 of Bartlett & Manchester, solved iteratively by
Algorithm 1 (reweighted l1), with piqp.

Decision variables (the QP's x): alpha (one per usable candidate: its acceleration is
alpha (s~ - f_p), eq. (13)), the CoM positions s_1..s_N and velocities v_1..v_N, and one
slack per time step on the cardinality bound of (16). Keeping s and v as variables, tied
by the one-step form of (1) (s_{n+1} = s_n + t v_n + t^2/2 a_n, v_{n+1} = v_n + t a_n, which
unrolls to (2): ``model.rollout`` and the tests check that), makes every matrix block-banded
in time, so piqp's sparse LDL^T sets up and solves a 4.5 s horizon with 600 candidates in
about 15 ms (measured: docs/reports/slip_guide.md); the condensed form (alpha only, through
P) has a dense N k x N k Hessian.

MOSEK, the paper's solver, is closed; piqp is the project's QP solver (the MPFC's and the
DCM planner's search), open, well kept and an interior-point method like MOSEK, which suits a
QP whose active set (which alphas are 0) is the answer. It has no warm start (nor needs one
much: an interior-point method gains little from one), so each iteration of Algorithm 1 is
set up afresh; "the previous solution as a warm start" of III-D enters as the reweighting.
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import piqp
import scipy.sparse as sp

from processes.slip_guide.candidates import (
    Candidates,
    in_friction_cone,
    nearest_within_reach,
)
from processes.slip_guide.params import SlipParams

SOLVED = "solved"
INFEASIBLE = "infeasible"
FAILED = "failed"
NO_CANDIDATES = "no_candidates"


@dataclass
class SlipPlan:
    """One plan: the CoM path s, v (N + 1, 3) from s_0, v_0; the candidates (time step and
    point index into the ``Candidates``, their positions, alpha and the leg vector s~ - f_p of
    the last iteration); per iteration of Algorithm 1 the cardinality (5) (the most contacts
    at any time step) and the l1 norm of alpha; times (wall and CPU, whole plan and QPs)."""

    status: str
    s: np.ndarray
    v: np.ndarray
    s_ref: np.ndarray
    step: np.ndarray
    point: np.ndarray
    positions: np.ndarray
    alpha: np.ndarray
    leg: np.ndarray
    usable: np.ndarray
    iterations: int = 0
    card_history: list[int] = field(default_factory=list)
    l1_history: list[float] = field(default_factory=list)
    #: why Algorithm 1 stopped: "card" (no time step over two contacts), "iterations" (n_rw
    #: reweightings spent), or "qp_infeasible" / "qp_failed" (a reweighted QP had no solution;
    #: the plan is the iteration before it, as Algorithm 1 keeps alpha^{r-1})
    stopped: str = ""
    wall_s: float = 0.0
    cpu_s: float = 0.0
    qp_wall_s: float = 0.0
    card_tol_mps2: float = 0.5

    @property
    def accel(self) -> np.ndarray:
        """Each candidate's acceleration of the CoM, alpha (s~ - f_p) of (13), (M, 3)."""
        return self.alpha[:, None] * self.leg

    @property
    def chosen(self) -> np.ndarray:
        """The contacts (5) counts: an acceleration above ``card_tol_mps2``."""
        return np.linalg.norm(self.accel, axis=1) > self.card_tol_mps2

    @property
    def contacts_per_step(self) -> np.ndarray:
        """card(a_n) of (5) at each of the N time steps."""
        n = len(self.s) - 1
        return np.bincount(self.step[self.chosen], minlength=n)


def reference_path(start: np.ndarray, yaw: float, speed_mps: float, params: SlipParams,
                   ground: Callable[[np.ndarray], np.ndarray], smooth_m: float = 0.4
                   ) -> tuple[np.ndarray, np.ndarray]:
    """The desired CoM path s* (N + 1, 3) and velocity ds*/dt (N, 3): a straight line at
    ``speed_mps`` along ``yaw`` from ``start`` (x, y), at ``com_height_m`` above the ground,
    the ground's height (``ground``: (M, 2) -> (M,), NaN off the terrain) averaged over
    ``smooth_m`` along the path so a stair's edge becomes a ramp the CoM can follow. The
    paper takes s* from "a higher level planner or remote operator" (I) and is silent on its
    height; this is ours."""
    n, dt = params.steps, params.dt_s
    heading = np.array([np.cos(yaw), np.sin(yaw)])
    along = np.arange(n + 1) * dt * speed_mps
    xy = np.asarray(start, float)[:2] + along[:, None] * heading
    offs = np.linspace(-0.5 * smooth_m, 0.5 * smooth_m, 21)
    probe = xy[:, None, :] + offs[None, :, None] * heading
    z = ground(probe.reshape(-1, 2)).reshape(n + 1, len(offs))
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # a probe row all over a gap: NaN
        zg = np.nanmean(np.where(np.isfinite(z), z, np.nan), axis=1)
    if np.all(np.isnan(zg)):
        raise ValueError("no ground under the whole reference path")
    ok = np.isfinite(zg)
    zg = np.interp(along, along[ok], zg[ok])  # across a gap: the ground either side
    s_ref = np.column_stack([xy, zg + params.com_height_m])
    return s_ref, np.diff(s_ref, axis=0) / dt


def temporal_difference(step: np.ndarray, point: np.ndarray, n: int) -> sp.csr_matrix:
    """The difference operator of (8): one row per surface point e and pair of consecutive
    time steps (i, i + 1) at which it is a candidate at either, alpha_{i+1, e} -
    alpha_{i, e}, a point that is no candidate at a time step taking alpha = 0 there (its
    force ends or begins). Not divided by t."""
    m = int(point.max()) + 1 if len(point) else 1
    cols = np.arange(len(step))
    first = step < n - 1  # -alpha_{i, e} in the row of pair (i, i + 1)
    second = step >= 1  # +alpha_{i, e} in the row of pair (i - 1, i)
    keys = np.concatenate([step[first] * m + point[first],
                           (step[second] - 1) * m + point[second]])
    _, rows = np.unique(keys, return_inverse=True)
    vals = np.concatenate([-np.ones(first.sum()), np.ones(second.sum())])
    c = np.concatenate([cols[first], cols[second]])
    return sp.csr_matrix((vals, (rows, c)), shape=(int(rows.max()) + 1 if len(rows) else 0,
                                                    len(step)))


class SlipPlanner:
    """Problem 2 + Algorithm 1 for one set of parameters; ``plan`` is a pure function of its
    inputs (no state is kept between plans)."""

    def __init__(self, params: SlipParams) -> None:
        self.p = params

    # -- Algorithm 1 ------------------------------------------------------------------------
    def plan(self, s0: np.ndarray, v0: np.ndarray, s_ref: np.ndarray, v_ref: np.ndarray,
             cands: Candidates) -> SlipPlan:
        """A plan from CoM position ``s0`` and velocity ``v0`` along ``s_ref`` (N + 1, 3)
        and ``v_ref`` (N, 3) over the candidate points ``cands``. Algorithm 1: solve Problem
        2, reweight (16) and move s~ to the solution, until no time step has more than two
        contacts or n_rw reweightings are spent."""
        p = self.p
        t0, c0 = time.perf_counter(), time.process_time()
        s0, v0 = np.asarray(s0, float), np.asarray(v0, float)
        # the candidates of the RKNN search, around the nominal CoM of each time step (II-A)
        step, point = nearest_within_reach(cands, s_ref[:-1], p.knn_k, p.reach_m)
        pos, nrm = cands.points[point], cands.normals[point]
        cost = cands.cost[point]
        s_tilde = s_ref.copy()
        s_tilde[0] = s0  # s~, first the desired path (III-A)
        alpha_prev = np.zeros(len(step))
        plan = SlipPlan(NO_CANDIDATES, s_tilde.copy(), np.vstack([v0, v_ref]), s_ref, step,
                        point, pos, alpha_prev.copy(), s_tilde[step] - pos,
                        np.zeros(len(step), bool), card_tol_mps2=p.card_tol_mps2)
        r = 0
        while len(step) and r <= p.rw_iterations:
            leg = s_tilde[step] - pos
            usable = in_friction_cone(leg, nrm, p.friction_mu)  # III-B, every iteration
            q0 = time.perf_counter()
            status, alpha_u, s, v = self._solve(s0, v0, s_ref, v_ref, step[usable],
                                                point[usable], leg[usable], cost[usable],
                                                alpha_prev[usable], r)
            plan.qp_wall_s += time.perf_counter() - q0
            if status != SOLVED:
                # a reweighting moved s~ so that the prefilter left a time step without the
                # support it needs (measured: a chasm at k = 10): keep the last solution
                if plan.iterations == 0:
                    plan.status = status
                plan.stopped = f"qp_{status}"
                break
            plan.status = status
            alpha = np.zeros(len(step))
            alpha[usable] = alpha_u
            plan.s, plan.v, plan.alpha, plan.leg, plan.usable = s, v, alpha, leg, usable
            plan.iterations = r + 1
            plan.card_history.append(int(plan.contacts_per_step.max(initial=0)))
            plan.l1_history.append(float(alpha.sum()))
            alpha_prev = alpha
            s_tilde = s.copy()  # the better approximation of s~ (Algorithm 1's caption)
            r += 1
            if plan.card_history[-1] <= 2:
                plan.stopped = "card"
                break
            plan.stopped = "iterations"
        plan.wall_s = time.perf_counter() - t0
        plan.cpu_s = time.process_time() - c0
        return plan

    # -- Problem 2 --------------------------------------------------------------------------
    def _solve(self, s0: np.ndarray, v0: np.ndarray, s_ref: np.ndarray, v_ref: np.ndarray,
               step: np.ndarray, point: np.ndarray, leg: np.ndarray, cost: np.ndarray,
               alpha_prev: np.ndarray, r: int
               ) -> tuple[str, np.ndarray, np.ndarray, np.ndarray]:
        """One QP of Problem 2 over the usable candidates; (status, alpha, s, v)."""
        p = self.p
        n, na, dt = len(s_ref) - 1, len(step), p.dt_s
        n3 = 3 * n
        nx = na + 2 * n3 + n  # [alpha, s_1..N, v_1..N, slack_0..N-1]
        g = np.asarray(p.gravity)
        # D alpha = the contacts' summed acceleration per time step, (3N, na): (13)
        rows = (3 * step[:, None] + np.arange(3)).ravel()
        cols = np.repeat(np.arange(na), 3)
        d = sp.csr_matrix((leg.ravel(), (rows, cols)), shape=(n3, na))
        eye = sp.identity(n3, format="csr")
        shift = sp.eye(n3, k=-3, format="csr")  # block n <- block n - 1
        zero_sl = sp.csr_matrix((n3, n))
        # kinematics (1)-(2) one step at a time, with the initial velocity
        a_v = sp.hstack([-dt * d, sp.csr_matrix((n3, n3)), eye - shift, zero_sl])
        a_s = sp.hstack([-0.5 * dt * dt * d, eye - shift, -dt * shift, zero_sl])
        b_v = np.tile(dt * g, n)
        b_v[:3] += v0
        b_s = np.tile(0.5 * dt * dt * g, n)
        b_s[:3] += s0 + dt * v0
        a_eq = sp.vstack([a_v, a_s], format="csc")
        b_eq = np.concatenate([b_v, b_s])
        # cost: (8) temporal consistency and (9) jerk act on alpha; (7) on s and v
        tc = temporal_difference(step, point, n) / dt
        diff = sp.eye(n - 1, n, k=1) - sp.eye(n - 1, n)
        jerk = sp.kron(diff, sp.identity(3)) @ d / dt  # j_i = (a_{i+1} - a_i) / t
        h_aa = 2.0 * (p.w_tc * (tc.T @ tc) + p.w_jerk * (jerk.T @ jerk))
        h = sp.block_diag([h_aa, 2.0 * p.w_path * sp.identity(n3),
                           2.0 * p.w_path * p.w_vel * sp.identity(n3),
                           sp.csr_matrix((n, n))], format="csc")
        c = np.zeros(nx)
        # (15) the cost-map-weighted l1 and (16) the reweighting term, both linear (alpha >= 0)
        c[:na] = p.w_env * cost + p.w_rw / (alpha_prev + p.rw_eps)
        c[na:na + n3] = -2.0 * p.w_path * s_ref[1:].ravel()
        c[na + n3:na + 2 * n3] = -2.0 * p.w_path * p.w_vel * v_ref.ravel()
        c[na + 2 * n3:] = p.card_slack_weight
        # bounds: push only and a_max per contact; the path tolerance (a box, per axis)
        lo = np.concatenate([np.zeros(na), s_ref[1:].ravel() - p.path_tol_m,
                             np.full(n3, -np.inf), np.zeros(n)])
        hi = np.concatenate([p.a_max_mps2 / np.linalg.norm(leg, axis=1),
                             s_ref[1:].ravel() + p.path_tol_m, np.full(n3, np.inf),
                             np.full(n, np.inf)])
        gmat, h_l, h_u = None, None, None
        if r > 0:
            # (16) <= 2.9 per time step, from the first reweighting on: at r = 0 alpha^{r-1}
            # = 0 and it would bound the summed alpha by 2.9 epsilon, which cannot hold the
            # robot up for any epsilon below the support's own scale (ours: the paper's
            # Algorithm 1 is silent). Softened by an exact l1 penalty on a slack, so that a
            # time step whose support was spread thin stays feasible (ours).
            w = 1.0 / (alpha_prev + p.rw_eps)
            gmat = sp.hstack([sp.csr_matrix((w, (step, np.arange(na))), shape=(n, na)),
                              sp.csr_matrix((n, 2 * n3)), -sp.identity(n)], format="csc")
            h_l, h_u = np.full(n, -np.inf), np.full(n, p.card_bound)
        solver = piqp.SparseSolver()
        st = solver.settings
        st.verbose = False
        st.eps_abs, st.eps_rel, st.max_iter = p.qp_eps_abs, p.qp_eps_rel, p.qp_max_iter
        st.compute_timings = False
        solver.setup(h, c, a_eq, b_eq, gmat, h_l, h_u, lo, hi)
        status = solver.solve()
        if status != piqp.PIQP_SOLVED:
            kind = INFEASIBLE if status == piqp.PIQP_PRIMAL_INFEASIBLE else FAILED
            return kind, np.zeros(na), np.zeros((n + 1, 3)), np.zeros((n + 1, 3))
        x = np.asarray(solver.result.x)
        alpha = np.maximum(x[:na], 0.0)
        s = np.vstack([s0, x[na:na + n3].reshape(n, 3)])
        v = np.vstack([v0, x[na + n3:na + 2 * n3].reshape(n, 3)])
        return SOLVED, alpha, s, v
