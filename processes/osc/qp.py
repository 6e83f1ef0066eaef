"""The condensed OSC quadratic program (14), solved with piqp's dense interior-point solver.

(14) is posed over (dv, u, lambda_h, lambda_c, eps). Here dv, lambda_h and eps are eliminated:
the dynamics (14b) with the holonomic rows (14c) give ``dv = G x + g0`` for the remaining
decision vector ``x = [u (10), lambda_c (3 per stance point)]``; the soft contact constraint
(14d) becomes a weighted residual (its slack ``eps`` is that residual). What is left is a QP
with at most 22 variables: box bounds for (14f) and the normal-force sign, and a linearised
friction pyramid for (14e). piqp has no warm start; the problem is set up once per contact
count and only ``update``-d afterwards. When the optimum can be certified in closed form (the
cost's unconstrained minimiser is feasible, or one active-set step on the constraints it
violates satisfies the KKT conditions) piqp is skipped (iterations reported as 0).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np
import piqp
from scipy.linalg import lapack

from .model import CassieModel

_potrf = lapack.dpotrf
_potrs = lapack.dpotrs


@dataclass
class QpWeights:
    """Regularisation weights of (14a) that are not task weights (see hw_config/gains/osc.yaml)."""

    contact_slack: float = 2000.0  # ||eps||^2 of (14d)
    torque: float = 1e-5  # ||u||^2
    force: float = 1e-7  # ||lambda_c||^2
    accel: float = 1e-5  # ||dv||^2
    torque_change: float = 1e-4  # ||u - u_prev||^2: conditions the QP without biasing tracking
    force_change: float = 1e-6  # ||lambda_c - lambda_c_prev||^2
    mu: float = 0.6  # friction coefficient of the pyramid (14e), inscribed (|fx|, |fy| <= mu fz)
    fz_max: float = 1500.0  # N per contact point
    standing_fz_min: float = 15.0  # N per contact point while standing: both feet stay loaded


@dataclass
class QpResult:
    """One solution: torques, contact forces (world, all 4 points), timings, status.

    ``dv`` is filled only by ``OscQP.recover()`` (not needed for the torques, so not per tick).
    """

    u: np.ndarray
    lam: np.ndarray
    dv: np.ndarray
    status: int
    iterations: int
    solve_s: float
    build_s: float


class TaskRows:
    """Stack of task rows ``J dv ~= b`` (``b = ydd_cmd - Jdot v``) with weight ``w`` per row.

    The arrays are views into the QP's own row stack, so tasks write where the QP reads.
    Tasks append rows with ``add``; ``reset`` is called once per tick.
    """

    def __init__(self, J: np.ndarray, b: np.ndarray, w: np.ndarray) -> None:
        self.J = J
        self.b = b
        self.w = w
        self.n = 0

    def reset(self) -> None:
        """Start a new tick with no rows."""
        self.n = 0

    def add(self, J: np.ndarray, Jdot_v: np.ndarray | float, ydd: np.ndarray | float,
            w: np.ndarray | float) -> None:
        """Append ``len(J)`` rows (a 1-D ``J`` is one row)."""
        k = 1 if J.ndim == 1 else J.shape[0]
        i = self.n
        self.J[i : i + k] = J
        np.subtract(ydd, Jdot_v, out=self.b[i : i + k])
        self.w[i : i + k] = w
        self.n = i + k


class _Solver:
    """One piqp dense solver for a fixed number of stance contact points."""

    def __init__(self, n: int, nc: int, u_max: np.ndarray, mu: float, fz_max: float,
                 fz_min: float = 0.0) -> None:
        nu = len(u_max)
        self.n = n
        self.solver = piqp.DenseSolver()
        s = self.solver.settings
        # 1e-6: the 1e-8/1e-9 defaults hit the iteration limit on some ticks (SYSTEM.md).
        s.eps_abs = 1e-6
        s.eps_rel = 1e-6
        s.eps_duality_gap_abs = 1e-6
        s.eps_duality_gap_rel = 1e-6
        s.max_iter = 60
        s.verbose = False
        # friction pyramid (14e): |fx| <= mu fz, |fy| <= mu fz, as 4 rows per point (G x <= 0)
        self.G = np.zeros((4 * nc, n), order="F")
        for i in range(nc):
            j = nu + 3 * i
            for r, (a, sgn) in enumerate(((0, 1.0), (0, -1.0), (1, 1.0), (1, -1.0))):
                self.G[4 * i + r, j + a] = sgn
                self.G[4 * i + r, j + 2] = -mu
        self.h_u = np.zeros(4 * nc)
        self.h_l = np.full(4 * nc, -np.inf)
        # bounds: torque limits (14f), 0 <= fz <= fz_max, fx and fy bounded through the pyramid
        self.x_l = np.full(n, -np.inf)
        self.x_u = np.full(n, np.inf)
        self.x_l[:nu] = -u_max
        self.x_u[:nu] = u_max
        for i in range(nc):
            self.x_l[nu + 3 * i + 2] = fz_min
            self.x_u[nu + 3 * i + 2] = fz_max
            for a in range(2):
                self.x_l[nu + 3 * i + a] = -mu * fz_max
                self.x_u[nu + 3 * i + a] = mu * fz_max
        self.ready = False
        self._no_lam = np.zeros(0)
        self.fz_max = fz_max
        self._bounds_changed = False
        self._caps_default = True  # x_u holds fz_max on every point
        self._fz_idx = nu + 2 + 3 * np.arange(nc)

    def set_fz_max(self, caps: np.ndarray) -> None:
        """Per-point upper bounds on the normal force (N) for the next solves (one per stance
        point, in row order): the double-stance weight transfer unloads the trailing foot."""
        default = caps.min() >= self.fz_max
        if default and self._caps_default:
            return  # the usual single-stance case: nothing to compare or copy
        idx = self._fz_idx[: len(caps)]
        cap = np.minimum(caps, self.fz_max)
        if not np.array_equal(self.x_u[idx], cap):
            self.x_u[idx] = cap
            self._bounds_changed = True
        self._caps_default = bool(default)

    def closed_form(self, P: np.ndarray, c: np.ndarray, max_steps: int = 4
                    ) -> np.ndarray | None:
        """The QP's optimum without piqp when it can be certified, else None.

        First the minimiser of the cost alone: if it satisfies every constraint it is the
        optimum (the problem is convex). Otherwise a few active-set steps: the violated
        constraints join a working set imposed as equalities (KKT system through the
        Cholesky factor of P and a small Schur complement), a constraint whose multiplier
        turns negative leaves it. A point that is feasible with every multiplier >= 0
        satisfies the KKT conditions of the full QP, so it is the optimum; if none is found
        within ``max_steps``, piqp decides.
        """
        cf, info = _potrf(P, lower=0, overwrite_a=0, clean=0)
        if info != 0:
            return None
        x0, _ = _potrs(cf, c, lower=0)
        x0 = -x0
        x = x0
        work: list[int] = []  # constraint ids: i < n lower bound i, n <= i < 2n upper, else G
        lam = self._no_lam
        tol = 1e-9
        for step in range(max_steps + 1):
            viol = self._violated(x, tol)
            if viol:
                work.extend(v for v in viol if v not in work)
            elif lam.size and float(lam.min()) < -tol:
                work.pop(int(np.argmin(lam)))
            else:
                return x  # feasible, multipliers >= 0: the KKT point of the full QP
            if not work or len(work) > self.n // 2 or step == max_steps:
                return None
            A, b = self._rows(work)
            PiAT, _ = _potrs(cf, A.T.copy(), lower=0)  # P^-1 A^T
            try:
                lam = np.linalg.solve(A @ PiAT, A @ x0 - b)
            except np.linalg.LinAlgError:
                return None
            x = x0 - PiAT @ lam
        return None

    def _violated(self, x: np.ndarray, tol: float) -> list[int]:
        """Ids of the constraints x violates (see ``closed_form`` for the numbering)."""
        n = self.n
        out = np.flatnonzero(x < self.x_l - tol).tolist()
        out += (np.flatnonzero(x > self.x_u + tol) + n).tolist()
        if self.G.shape[0]:
            out += (np.flatnonzero(self.G @ x > tol) + 2 * n).tolist()
        return out

    def _rows(self, work: list[int]) -> tuple[np.ndarray, np.ndarray]:
        """The working set as rows a_j x <= b_j."""
        n = self.n
        A = np.zeros((len(work), n))
        b = np.zeros(len(work))
        for r, j in enumerate(work):
            if j < n:
                A[r, j] = -1.0
                b[r] = -self.x_l[j]
            elif j < 2 * n:
                A[r, j - n] = 1.0
                b[r] = self.x_u[j - n]
            else:
                A[r] = self.G[j - 2 * n]
        return A, b

    def solve(self, P: np.ndarray, c: np.ndarray) -> tuple[int, int, np.ndarray]:
        """piqp on min 1/2 x'Px + c'x with the bounds and pyramid rows: (status, iters, x)."""
        if not self.ready:
            if self.G.shape[0]:
                self.solver.setup(P, c, None, None, self.G, self.h_l, self.h_u, self.x_l, self.x_u)
            else:
                self.solver.setup(P, c, None, None, None, None, None, self.x_l, self.x_u)
            self.ready = True
        elif self._bounds_changed:
            self.solver.update(P=P, c=c, x_u=self.x_u)
        else:
            self.solver.update(P=P, c=c)
        self._bounds_changed = False
        status = self.solver.solve()
        res = self.solver.result
        return int(status.value), int(res.info.iter), res.x


class OscQP:
    """Builds and solves the condensed (14) for one tick, with preallocated work arrays."""

    def __init__(self, model: CassieModel, weights: QpWeights | None = None,
                 closed_form_first: bool = True) -> None:
        self.model = model
        #: try the closed-form optimum first (unconstrained, or one active-set step); piqp
        #: only when that cannot be certified optimal
        self.closed_form_first = closed_form_first
        self.wts = weights or QpWeights()
        nv, nu = model.nv, model.nu
        self.nv, self.nu = nv, nu
        nh, ncp = model.n_holonomic, model.n_contact_points
        self.nh = nh
        self._solvers: dict[tuple[int, float], _Solver] = {}
        # rhs rows for M^-1: [Jh (14); B^T (nu); Jc of stance points (<= 12); -h (1)]
        self._rhs = np.zeros((nh + nu + 3 * ncp + 1, nv))
        self._rhs[nh : nh + nu] = model.B.T
        self._Y = np.zeros_like(self._rhs)
        max_task_rows = 64
        na = nv if self.wts.accel > 0.0 else 0
        self._r0 = nh + na  # first task row in the stack
        mr = self._r0 + max_task_rows + 3 * ncp
        self._Jall = np.zeros((mr, nv))
        self._brows = np.zeros(mr)
        self._wrows = np.zeros(mr)
        self._Jall[nh : nh + na] = np.eye(nv)[:na]  # ||dv||^2 rows: constant
        self._wrows[nh : nh + na] = self.wts.accel
        #: where the tasks write their rows (views into the stack above)
        self.rows = TaskRows(self._Jall[self._r0 : self._r0 + max_task_rows],
                             self._brows[self._r0 : self._r0 + max_task_rows],
                             self._wrows[self._r0 : self._r0 + max_task_rows])
        self._reg_cache: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        self._x: np.ndarray | None = None
        self._S = np.zeros((nh, 1))
        self._R = np.zeros((nh, nu + 3 * ncp + 2))
        self._xs = np.zeros(nu + 3 * ncp + 2)
        self._row_cache: dict[bytes, np.ndarray] = {}
        self._fz_default = np.full(ncp, self.wts.fz_max)
        self.u_prev = np.zeros(nu)
        self.lam_prev = np.zeros(3 * ncp)  # per contact point, kept across contact changes
        self.u = np.zeros(nu)
        self.lam = np.zeros(3 * ncp)
        self.dv = np.zeros(nv)
        self.lam_h = np.zeros(nh)
        #: Contact-moment cost w ||A lambda - target||^2 on the first ``moment_count`` rows:
        #: each row of A gives the moment of the contact forces about a point along an axis
        #: (the MPFC ankle torque of Section V-D, the double-stance CoP of (2)); 0 rows: off
        self.moment_rows = np.zeros((2, 3 * ncp))
        self.moment_target = np.zeros(2)
        self.moment_count = 0
        self.moment_weight = 0.0
        self.last_status = 0

    def solve(self, tasks: TaskRows, stance: np.ndarray, fz_min: float = 0.0,
              fz_max: np.ndarray | None = None) -> QpResult:
        """Build the condensed QP for the model's current state and solve it.

        ``stance`` is a bool mask over the 4 foot contact points (left front/rear, right
        front/rear); only those carry forces and the soft contact constraint (14d).
        ``fz_min`` is a lower bound on each stance point's normal force (standing keeps both
        feet loaded with it). ``fz_max`` (4 values, one per contact point) caps the normal
        forces below the configured limit (the double-stance weight transfer).
        """
        t0 = time.perf_counter()
        m = self.model
        nu, nh = self.nu, self.nh
        rows = self._rows_of(stance)
        nc = len(rows) // 3
        n = nu + 3 * nc
        Jc = m.Jc[rows]

        # M^-1 applied to every generalized-force direction at once (one factorization):
        # Y rows = (M^-1 [Jh^T, B, Jc^T, -h])^T.
        k = nh + nu + 3 * nc + 1
        rhs = self._rhs[:k]
        rhs[:nh] = m.Jh
        rhs[nh + nu : k - 1] = Jc
        np.negative(m.h, out=rhs[k - 1])
        Y = self._Y[:k]
        m.solve_M(Y, rhs)

        # Every row of the cost, stacked: [Jh; I (||dv||^2, constant); tasks; stance Jc (14d)]
        # (the task rows were written in place by the tasks through self.rows).
        r0 = self._r0
        nt = tasks.n
        end = r0 + nt + 3 * nc
        J = self._Jall[:end]
        J[:nh] = m.Jh
        J[r0 + nt : end] = Jc
        b = self._brows[nh:end]
        w = self._wrows[nh:end]
        np.negative(m.Jc_dot_v[rows], out=self._brows[r0 + nt : end])
        self._wrows[r0 + nt : end] = self.wts.contact_slack
        W = J @ Y.T  # (end, k): one product gives Lam, Jh M^-1 F and every cost row
        # (14c) eliminates lambda_h:  Lam lambda_h = bh - Jh M^-1 f,  Lam = Jh M^-1 Jh^T
        Rh = self._R[:, : k - nh + 1]
        np.negative(W[:nh, nh:], out=Rh[:, : k - nh])
        np.negative(m.Jh_dot_v, out=Rh[:, k - nh])  # bh of (14c)
        cf, info = _potrf(W[:nh, :nh], lower=0, overwrite_a=0, clean=0)
        if info != 0:
            raise np.linalg.LinAlgError("holonomic Gram matrix not positive definite")
        S, _ = _potrs(cf, Rh, lower=0)  # lambda_h = S [x; 1; 1]
        # the cost rows as affine functions of x: A dv = W[:, nh:] + W[:, :nh] S
        AG = W[nh:, :nh] @ S
        AG[:, : n + 1] += W[nh:, nh:]
        resid0 = AG[:, n]
        resid0 += AG[:, n + 1]
        resid0 -= b
        sw = np.sqrt(w)
        AGw = AG[:, :n] * sw[:, None]
        resid0 *= sw
        P = AGw.T @ AGw
        c = AGw.T @ resid0
        self._S = S
        self._x_rows = rows
        # torque / force magnitudes and their change from the previous tick (diagonal terms)
        reg, diag = self._reg_of(n)
        P.flat[diag] += reg
        wdt, wdf = self.wts.torque_change, self.wts.force_change
        c[:nu] -= wdt * self.u_prev
        c[nu:] -= wdf * self.lam_prev[rows]
        k = self.moment_count
        if k and self.moment_weight > 0.0:
            # moments of the contact forces (the ALIP's u of (1) about its contact point)
            A = self.moment_rows[:k, rows]
            wA = self.moment_weight * A
            P[nu:, nu:] += A.T @ wA
            c[nu:] -= wA.T @ self.moment_target[:k]

        solver = self._solvers.get((nc, fz_min))
        if solver is None:
            solver = _Solver(n, nc, m.u_max, self.wts.mu, self.wts.fz_max, fz_min)
            self._solvers[(nc, fz_min)] = solver
        solver.set_fz_max(self._fz_default[:nc] if fz_max is None else fz_max[stance])
        t1 = time.perf_counter()
        x = solver.closed_form(P, c) if self.closed_form_first else None
        if x is not None:
            status, iters = 1, 0
        else:
            status, iters, x = solver.solve(P.T, c)  # P symmetric: P.T is its F-ordered view
        t2 = time.perf_counter()
        self.last_status = status
        if status == 1 and math.isfinite(float(x.sum())):
            self.u[:] = x[:nu]
            self.lam[:] = 0.0
            self.lam[rows] = x[nu:]
            self.u_prev[:] = self.u
            self.lam_prev[:] = self.lam
            self._x = x
        else:
            self._x = None
        return QpResult(self.u, self.lam, self.dv, status, iters, t2 - t1, t1 - t0)

    def recover(self) -> None:
        """Fill ``dv`` (14b) and ``lam_h`` (14c) for the last solution (tests, debugging)."""
        if self._x is None:
            return
        x, nh = self._x, self.nh
        n = len(x)
        xs = self._xs[: n + 2]
        xs[:n] = x
        xs[n:] = 1.0
        np.dot(self._S, xs, out=self.lam_h)
        Y = self._Y[: nh + n + 1]
        np.dot(Y[nh:].T, xs[: n + 1], out=self.dv)
        self.dv += Y[:nh].T @ self.lam_h

    def _reg_of(self, n: int) -> tuple[np.ndarray, np.ndarray]:
        """Diagonal regularisation of (14a) and the flat diagonal indices, for n variables."""
        r = self._reg_cache.get(n)
        if r is None:
            reg = np.empty(n)
            reg[: self.nu] = self.wts.torque + self.wts.torque_change
            reg[self.nu :] = self.wts.force + self.wts.force_change
            r = (reg, np.arange(n) * (n + 1))
            self._reg_cache[n] = r
        return r

    def _rows_of(self, stance: np.ndarray) -> np.ndarray:
        """Force/Jacobian row indices of the stance points (cached per mask)."""
        key = stance.tobytes()
        r = self._row_cache.get(key)
        if r is None:
            idx = np.flatnonzero(stance)
            r = (3 * idx[:, None] + np.arange(3)).reshape(-1)
            self._row_cache[key] = r
        return r
