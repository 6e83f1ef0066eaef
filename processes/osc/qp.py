"""The condensed OSC quadratic program (14), solved exactly by a compiled active-set method.

(14) is posed over (dv, u, lambda_h, lambda_c, eps). Here dv, lambda_h and eps are eliminated:
the dynamics (14b) with the holonomic rows (14c) give ``dv = G x + g0`` for the remaining
decision vector ``x = [u (10), lambda_c (3 per stance point)]``; the soft contact constraint
(14d) becomes a weighted residual (its slack ``eps`` is that residual). What is left is a QP
with at most 22 variables: box bounds for (14f) and the normal-force sign, and a linearised
friction pyramid for (14e). A compiled dual active-set method (``activeset``) finds its
exact optimum, accepted only when it satisfies the KKT conditions of the whole QP (piqp is
then skipped: iterations reported as 0). piqp's dense interior-point solver is the last
resort when that certificate fails; it has no warm start, so it is set up once per contact
count and only ``update``-d afterwards.

The condensation (M^-1 through MuJoCo's sparse factor, the holonomic Schur complement, every
cost row as an affine function of x, the cost's P and c) is one compiled kernel (numba,
cached on disk): per tick it replaced ~40 numpy/LAPACK calls and one ``mj_solveM``.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass

import numba
import numpy as np
import piqp

from runtime.params import spec

from .activeset import cholesky_upper, solve_dual_active_set
from .model import CassieModel


@dataclass(frozen=True)
class QpWeights:
    """Regularisation weights of (14a) that are not task weights (``qp:`` of
    hw_config/gains/osc.yaml)."""

    contact_slack: float = spec(2000.0, lo=0.0)  # ||eps||^2 of (14d)
    torque: float = spec(1e-5, lo=0.0)  # ||u||^2
    force: float = spec(1e-7, lo=0.0)  # ||lambda_c||^2
    accel: float = spec(1e-5, lo=0.0)  # ||dv||^2
    #: ||u - u_prev||^2: conditions the QP without biasing tracking
    torque_change: float = spec(1e-4, lo=0.0)
    force_change: float = spec(1e-6, lo=0.0)  # ||lambda_c - lambda_c_prev||^2
    #: friction coefficient of the pyramid (14e), inscribed (|fx|, |fy| <= mu fz)
    mu: float = spec(0.6, lo=0.0, hi=2.0, lo_open=True)
    fz_max: float = spec(1500.0, lo=0.0, unit="N")  # per contact point
    #: per contact point while standing: both feet stay loaded
    standing_fz_min: float = spec(15.0, lo=0.0, unit="N")


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


#: Sources of task rows (``TaskRows.add_row``): a row is ``c0 * (S[i0] + c1 * S[i1])`` over
#: the stacked rows S = [J_com (3, world); Jc (12: 3 per contact point, world); unit rows
#: (one per dof: a joint or floating-base velocity); rows given explicitly with ``add``].
ROW_COM = 0
ROW_CONTACT = 3
ROW_DOF = 15


class TaskRows:
    """Stack of task rows ``J dv ~= b`` (``b = ydd_cmd - Jdot v``) with weight ``w`` per row.

    A row's ``J`` is named, not copied: ``add_row`` gives one or two source rows of the model
    (``ROW_COM``/``ROW_CONTACT``/``ROW_DOF``) and their coefficients, and the QP's compiled
    condensation reads them there. ``add`` takes explicit rows (any ``J``) as before.
    ``reset`` is called once per tick.
    """

    def __init__(self, nv: int, max_rows: int = 64) -> None:
        self.nv = nv
        #: per row [i0, i1] and [c0, c1, b, w] (the compiled tasks and QP read these two)
        self.ri = np.zeros((max_rows, 2), dtype=np.int64)
        self.rf = np.zeros((max_rows, 4))
        self.i0, self.i1 = self.ri[:, 0], self.ri[:, 1]
        self.c0, self.c1, self.b, self.w = (self.rf[:, j] for j in range(4))
        #: explicit rows given with ``add`` (source ``ROW_DOF + nv + row``)
        self.dense = np.zeros((max_rows, nv))
        self.n = 0

    def reset(self) -> None:
        """Start a new tick with no rows."""
        self.n = 0

    def add_row(self, i0: int, c0: float, b: float, w: float, i1: int = -1,
                c1: float = 0.0) -> None:
        """Append the row ``c0 * (S[i0] + c1 * S[i1])`` (``i1 = -1``: ``c0 * S[i0]``) with
        right-hand side ``b`` and weight ``w``."""
        i = self.n
        self.ri[i] = i0, i1
        self.rf[i] = c0, c1, b, w
        self.n = i + 1

    def add(self, J: np.ndarray, Jdot_v: np.ndarray | float, ydd: np.ndarray | float,
            w: np.ndarray | float) -> None:
        """Append ``len(J)`` explicit rows (a 1-D ``J`` is one row)."""
        k = 1 if J.ndim == 1 else J.shape[0]
        i = self.n
        self.dense[i : i + k] = J
        self.i0[i : i + k] = ROW_DOF + self.nv + np.arange(i, i + k)
        self.c0[i : i + k] = 1.0
        self.i1[i : i + k] = -1
        np.subtract(ydd, Jdot_v, out=self.b[i : i + k])
        self.w[i : i + k] = w
        self.n = i + k

    def matrix(self, model: CassieModel) -> np.ndarray:
        """The rows' ``J`` as a dense (n, nv) matrix for the model's current state (tests)."""
        src = np.vstack([model.J_com, model.Jc, np.eye(self.nv), self.dense])
        out = np.zeros((self.n, self.nv))
        for r in range(self.n):
            row = src[self.i0[r]].copy()
            if self.i1[r] >= 0:
                row += self.c1[r] * src[self.i1[r]]
            out[r] = self.c0[r] * row
        return out


def _task_arrays(t: TaskRows) -> tuple[np.ndarray, ...]:
    """The arrays of a task-row stack, in the condensation kernel's argument order."""
    return (t.ri, t.rf, t.dense)


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
        self.fz_max = fz_max
        self._bounds_changed = False
        self._caps_default = True  # x_u holds fz_max on every point
        self.fz_min = fz_min
        self._floors_default = True  # x_l holds fz_min on every point
        self._fz_idx_list = [nu + 2 + 3 * i for i in range(nc)]
        # the compiled active-set solver's constraint rows and scratch
        self._Gc = np.ascontiguousarray(self.G)
        ncon = 2 * n + 4 * nc
        self._x = np.zeros(n)
        self._lam = np.zeros(n)
        self._iwork = np.zeros(n + ncon, dtype=np.int64)
        self._work = np.zeros((4 * n + 7, n))
        self._viol = np.zeros(ncon)
        self.max_steps = 100
        self._as_args = (self.x_l, self.x_u, self._Gc, self.h_u, self._x, self._lam,
                         self._iwork, self._work, self._viol)
        self.steps = 0  # active-set steps and active constraints of the last closed_form
        self.n_active = 0

    def set_fz_max(self, caps: Sequence[float]) -> None:
        """Per-point upper bounds on the normal force (N) for the next solves (one per stance
        point, in row order): the double-stance weight transfer unloads the trailing foot."""
        fmax = self.fz_max
        default = min(caps) >= fmax
        if default and self._caps_default:
            return  # the usual single-stance case: nothing to compare or copy
        self._write_fz(self.x_u, [min(cap, fmax) for cap in caps])
        self._caps_default = default

    def set_fz_min(self, floors: Sequence[float] | None) -> None:
        """Per-point lower bounds on the normal force (N) for the next solves (one per stance
        point, in row order; None: ``fz_min`` on every point): the first double stance out
        of standing keeps the leading foot loaded."""
        if floors is None:
            if self._floors_default:
                return
            floors = [self.fz_min] * len(self._fz_idx_list)
        self._write_fz(self.x_l, [max(floor, self.fz_min) for floor in floors])
        self._floors_default = all(f <= self.fz_min for f in floors)

    def _write_fz(self, bounds: np.ndarray, values: Sequence[float]) -> None:
        """Write per-point normal-force bounds into ``bounds`` (x_l or x_u), noting a change
        for piqp's next update."""
        for j, value in zip(self._fz_idx_list, values, strict=True):
            if bounds[j] != value:
                bounds[j] = value
                self._bounds_changed = True

    def closed_form(self, P: np.ndarray, c: np.ndarray) -> np.ndarray | None:
        """The QP's exact optimum without piqp when it can be certified, else None.

        The compiled dual active-set method (``activeset.solve_dual_active_set``): from the
        cost's unconstrained minimiser, the most violated constraint joins the active set
        until none is violated, a constraint whose multiplier would turn negative leaving
        it. The point is returned only when it satisfies the KKT conditions of the full QP
        (feasible within 1e-9, multipliers >= 0, stationary to rounding), so it is the
        optimum; otherwise (never seen on the OSC's QPs) piqp decides.
        """
        status, steps, nact = solve_dual_active_set(P, c, *self._as_args, 1e-9, self.max_steps)
        self.steps, self.n_active = steps, nact
        return self._x if status == 1 else None

    def solve(self, P: np.ndarray, c: np.ndarray) -> tuple[int, int, np.ndarray]:
        """piqp on min 1/2 x'Px + c'x with the bounds and pyramid rows: (status, iters, x)."""
        if not self.ready:
            if self.G.shape[0]:
                self.solver.setup(P, c, None, None, self.G, self.h_l, self.h_u, self.x_l, self.x_u)
            else:
                self.solver.setup(P, c, None, None, None, None, None, self.x_l, self.x_u)
            self.ready = True
        elif self._bounds_changed:
            self.solver.update(P=P, c=c, x_l=self.x_l, x_u=self.x_u)
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
        #: try the compiled exact active-set solve first; piqp only when its optimum cannot
        #: be certified by the KKT conditions
        self.closed_form_first = closed_form_first
        self.wts = weights or QpWeights()
        nv, nu = model.nv, model.nu
        self.nv, self.nu = nv, nu
        nh, ncp = model.n_holonomic, model.n_contact_points
        self.nh = nh
        self._solvers: dict[tuple[int, float], _Solver] = {}
        ncp3 = 3 * ncp
        nmax = nu + ncp3
        m_max = nv + 64 + ncp3  # cost rows: ||dv||^2, tasks, soft contact
        self._buf = np.zeros(nv * (2 * nh + nmax + 1 + 15) + nh * (nh + nmax + 1)
                             + 15 * (nmax + 2) + m_max * (nmax + 1) + 2 * (nmax + 2))
        #: where the tasks write their rows
        self.rows = TaskRows(nv, 64)
        # per variable count n: P (n, n), S (nh, n + 2), G (nv, n + 2)
        self._Pbuf = {n: np.zeros((n, n)) for n in range(nu, nmax + 1, 3)}
        self._Sbuf = {n: np.zeros((nh, n + 2)) for n in self._Pbuf}
        self._Gbuf = {n: np.zeros((nv, n + 2)) for n in self._Pbuf}
        self._c = np.zeros(nmax)
        w = self.wts
        #: [accel, contact_slack, u reg, lambda reg, u change, lambda change, moment weight]
        self._wts = np.array([w.accel, w.contact_slack, w.torque + w.torque_change,
                              w.force + w.force_change, w.torque_change, w.force_change, 0.0])
        self._x: np.ndarray | None = None
        self._xs = np.zeros(nmax + 2)
        self._row_cache: dict[bytes, tuple[np.ndarray, list[int]]] = {}
        mdl = model.m
        self._M_rownnz = np.ascontiguousarray(mdl.M_rownnz, dtype=np.int64)
        self._M_rowadr = np.ascontiguousarray(mdl.M_rowadr, dtype=np.int64)
        self._M_colind = np.ascontiguousarray(mdl.M_colind, dtype=np.int64)
        self._motor_dof = np.ascontiguousarray(model.motor_dof, dtype=np.int64)
        self._qLD = model.d.qLD
        self._qLDiagInv = model.d.qLDiagInv
        self._fz_default = [self.wts.fz_max] * ncp
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
        self._last: tuple[np.ndarray, np.ndarray, _Solver] | None = None
        # the condensation kernel's array arguments (fixed objects, filled in place)
        m = model
        self._cargs = (m.Jh, m.Jh_dot_v, m.h, m.Jc, m.Jc_dot_v, m.J_com, self._qLD,
                       self._qLDiagInv, self._M_rownnz, self._M_rowadr, self._M_colind,
                       self._motor_dof, self._wts, self.u_prev, self.lam_prev, self.moment_rows,
                       self.moment_target, self._buf)
        self._task_args = _task_arrays(self.rows)
        self._nargs = {n: (self._Sbuf[n], self._Gbuf[n], self._Pbuf[n], self._c[:n])
                       for n in self._Pbuf}
        # compile the kernel (or load it from numba's on-disk cache) now, not on the first tick
        self._build(self.rows, self._rows_of(np.ones(ncp, dtype=bool))[0])
        _store(np.zeros(nmax), self._rows_of(np.ones(ncp, dtype=bool))[0], np.zeros(nu),
               np.zeros(ncp3), np.zeros(nu), np.zeros(ncp3))
        _Solver(nu + 3, 1, np.ones(nu), 0.5, 1.0).closed_form(np.eye(nu + 3), np.ones(nu + 3))
        # the solvers of standing (4 points, loaded) and walking (4 or 2 points), made now: a
        # first tick in each would otherwise pay for their set-up
        for nc, fz_min in ((4, self.wts.standing_fz_min), (4, 0.0), (2, 0.0)):
            self._solver(nc, fz_min)

    def solve(self, tasks: TaskRows, stance: np.ndarray, fz_min: float = 0.0,
              fz_max: np.ndarray | None = None,
              fz_floor: np.ndarray | None = None) -> QpResult:
        """Build the condensed QP for the model's current state and solve it.

        ``stance`` is a bool mask over the 4 foot contact points (left front/rear, right
        front/rear); only those carry forces and the soft contact constraint (14d).
        ``fz_min`` is a lower bound on each stance point's normal force (standing keeps both
        feet loaded with it). ``fz_max`` (4 values, one per contact point) caps the normal
        forces below the configured limit (the double-stance weight transfer).
        """
        t0 = time.perf_counter()
        rows, points = self._rows_of(stance)
        nc = len(points)
        P, c = self._build(tasks, rows)
        solver = self._solvers.get((nc, fz_min))
        if solver is None:
            solver = self._solver(nc, fz_min)
        solver.set_fz_max(self._fz_default[:nc] if fz_max is None
                          else [fz_max[i] for i in points])
        solver.set_fz_min(None if fz_floor is None else [fz_floor[i] for i in points])
        self._last = (P, c, solver)
        t1 = time.perf_counter()
        x = solver.closed_form(P, c) if self.closed_form_first else None
        if x is not None:
            status, iters = 1, 0
        else:
            status, iters, x = solver.solve(P.T, c)  # P symmetric: P.T is its F-ordered view
            # piqp's answer is a view of its own memory: as a plain C array it takes the one
            # _store signature compiled at construction (else the first piqp tick of a live
            # run compiled another, 0.22 s, as the holder let go; measured on a fresh clone)
            x = np.require(x, np.float64, ("C", "W"))
        t2 = time.perf_counter()
        self.last_status = status
        # a solution becomes u, lambda (all 4 points) and the previous-tick terms
        if status == 1 and _store(x, rows, self.u, self.lam, self.u_prev, self.lam_prev):
            self._x = x
        else:
            self._x = None
        return QpResult(self.u, self.lam, self.dv, status, iters, t2 - t1, t1 - t0)

    def _solver(self, nc: int, fz_min: float) -> _Solver:
        """The solver for ``nc`` stance points and a normal-force floor ``fz_min`` (made once)."""
        s = _Solver(self.nu + 3 * nc, nc, self.model.u_max, self.wts.mu, self.wts.fz_max,
                    fz_min)
        self._solvers[(nc, fz_min)] = s
        return s

    def last_problem(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                                    np.ndarray]:
        """Copies of the last tick's QP: (P, c, x_l, x_u, G) of min 1/2 x'Px + c'x subject to
        x_l <= x <= x_u and G x <= 0 (checks against other solvers)."""
        P, c, s = self._last
        return P.copy(), c.copy(), s.x_l.copy(), s.x_u.copy(), s._Gc.copy()

    def _build(self, tasks: TaskRows, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The condensed (14) for the stance rows ``rows``: its (P, c), from the compiled
        kernel (buffers reused from tick to tick)."""
        n = self.nu + len(rows)
        P = self._Pbuf[n]
        c = self._c[:n]
        k = self.moment_count
        self._wts[6] = self.moment_weight if k else 0.0
        # the arrays (fixed objects, filled in place) are gathered once: see __init__
        targs = self._task_args if tasks is self.rows else _task_arrays(tasks)
        info = _condense(*self._cargs, *targs, rows, tasks.n, k, *self._nargs[n])
        if info != 0:
            raise np.linalg.LinAlgError("holonomic Gram matrix not positive definite")
        return P, c

    def recover(self) -> None:
        """Fill ``dv`` (14b) and ``lam_h`` (14c) for the last solution (tests, debugging)."""
        if self._x is None:
            return
        x = self._x
        n = len(x)
        xs = self._xs[: n + 2]
        xs[:n] = x
        xs[n:] = 1.0
        np.dot(self._Sbuf[n], xs, out=self.lam_h)  # lambda_h = S [x; 1; 1]
        np.dot(self._Gbuf[n], xs, out=self.dv)  # dv = G [x; 1; 1]

    def _rows_of(self, stance: np.ndarray) -> tuple[np.ndarray, list[int]]:
        """Force/Jacobian row indices and the point indices of the stance points (cached per
        mask)."""
        key = stance.tobytes()
        r = self._row_cache.get(key)
        if r is None:
            idx = np.flatnonzero(stance)
            r = ((3 * idx[:, None] + np.arange(3)).reshape(-1), idx.tolist())
            self._row_cache[key] = r
        return r


# ---------------------------------------------------------------------- compiled kernels
_jit = numba.njit(cache=True, nogil=True)


@_jit
def _store(x: np.ndarray, rows: np.ndarray, u: np.ndarray, lam: np.ndarray,
           u_prev: np.ndarray, lam_prev: np.ndarray) -> bool:
    """A finite solution x = [u, lambda_c of ``rows``] into u, lam (zero off the stance
    rows) and the previous-tick copies; False (nothing written) if x is not finite."""
    for i in range(x.size):
        if not math.isfinite(x[i]):
            return False
    nu = u.size
    for i in range(nu):
        u[i] = x[i]
        u_prev[i] = x[i]
    for i in range(lam.size):
        lam[i] = 0.0
    for r in range(rows.size):
        lam[rows[r]] = x[nu + r]
    for i in range(lam.size):
        lam_prev[i] = lam[i]
    return True


@_jit
def _solve_ld(X: np.ndarray, k: int, qLD: np.ndarray, qLDiagInv: np.ndarray,
              rownnz: np.ndarray, rowadr: np.ndarray, colind: np.ndarray) -> None:
    """``X[:, :k] <- M^-1 X[:, :k]`` for k right-hand sides stored as columns (nv, k), with
    MuJoCo's sparse factor M = L' D L (CSR rows; mj_solveLD of engine_core_smooth.c):
    x <- L^-T x, x <- D^-1 x, x <- L^-1 x, each sparse update done on all k columns at once."""
    nv = X.shape[0]
    for i in range(nv - 1, -1, -1):
        start = rowadr[i]
        for adr in range(start, start + rownnz[i] - 1):
            lij = qLD[adr]
            j = colind[adr]
            for r in range(k):
                X[j, r] -= lij * X[i, r]
    for i in range(nv):
        d = qLDiagInv[i]
        for r in range(k):
            X[i, r] *= d
    for i in range(nv):
        start = rowadr[i]
        for adr in range(start, start + rownnz[i] - 1):
            lij = qLD[adr]
            j = colind[adr]
            for r in range(k):
                X[i, r] -= lij * X[j, r]


@_jit
def _cholesky_solve(A: np.ndarray, B: np.ndarray, nb: int) -> int:
    """Solve ``A X = B[:, :nb]`` in place (X into B) for symmetric positive definite A (its
    upper triangle is read and overwritten by the factor U, A = U'U). 0, or 1 if not PD."""
    n = A.shape[0]
    if not cholesky_upper(A, A):
        return 1
    # U' Y = B, then U X = Y, a row of B (all nb columns) at a time
    for i in range(n):
        for k in range(i):
            u = A[k, i]
            for col in range(nb):
                B[i, col] -= u * B[k, col]
        d = A[i, i]
        for col in range(nb):
            B[i, col] /= d
    for i in range(n - 1, -1, -1):
        for k in range(i + 1, n):
            u = A[i, k]
            for col in range(nb):
                B[i, col] -= u * B[k, col]
        d = A[i, i]
        for col in range(nb):
            B[i, col] /= d
    return 0


@_jit
def _condense(Jh: np.ndarray, Jh_dot_v: np.ndarray, h: np.ndarray, Jc: np.ndarray,
              Jc_dot_v: np.ndarray, J_com: np.ndarray, qLD: np.ndarray, qLDiagInv: np.ndarray,
              rownnz: np.ndarray, rowadr: np.ndarray, colind: np.ndarray, motor_dof: np.ndarray,
              wts: np.ndarray, u_prev: np.ndarray, lam_prev: np.ndarray,
              moment_rows: np.ndarray, moment_target: np.ndarray, buf: np.ndarray,
              ri: np.ndarray, rf: np.ndarray, tdense: np.ndarray, rows: np.ndarray, nt: int,
              nmom: int, S: np.ndarray, G: np.ndarray, P: np.ndarray, c: np.ndarray) -> int:
    """The condensed QP (14) over x = [u, lambda_c of the stance rows]: ``P`` and ``c`` of
    min 1/2 x'Px + c'x, with ``S`` (lambda_h = S [x; 1; 1], (nh, n + 2)) and ``G``
    (dv = G [x; 1; 1], (nv, n + 2)), both C-contiguous. ``buf`` is flat scratch. Products
    go through BLAS (numba's np.dot), the rest is plain loops. Returns 0, or 1 when the
    holonomic Gram matrix Jh M^-1 Jh' is not positive definite."""
    nh, nv = Jh.shape
    nu = motor_dof.size
    n3 = rows.size
    n = nu + n3
    nf = n + 1  # generalized-force directions besides Jh': B (nu), Jc' (n3), -h (1)
    na = nv if wts[0] > 0.0 else 0
    m = na + nt + n3  # cost rows (14a): ||dv||^2, tasks, soft contact (14d)
    k = nh + nf
    o = 0
    Y = buf[o : o + nv * k].reshape((nv, k))
    o += nv * k
    Yh = buf[o : o + nv * nh].reshape((nv, nh))
    o += nv * nh
    W = buf[o : o + nh * k].reshape((nh, k))
    o += nh * k
    src = buf[o : o + 15 * nv].reshape((15, nv))
    o += 15 * nv
    SG = buf[o : o + 15 * (n + 2)].reshape((15, n + 2))
    o += 15 * (n + 2)
    Aw = buf[o : o + m * n].reshape((m, n))
    o += m * n
    rw = buf[o : o + m]
    o += m
    row = buf[o : o + n + 2]
    o += n + 2
    tmp = buf[o : o + n + 2]
    # (13)/(14b): M dv = Jh' lambda_h + [B, Jc', -h] [x; 1]: Y = M^-1 [Jh', B, Jc', -h]
    for i in range(nv):
        for r in range(nh):
            Y[i, r] = Jh[r, i]
        for j in range(nh, k):
            Y[i, j] = 0.0
        for r in range(n3):
            Y[i, nh + nu + r] = Jc[rows[r], i]
        Y[i, k - 1] = -h[i]
    for a in range(nu):
        Y[motor_dof[a], nh + a] = 1.0
    _solve_ld(Y, k, qLD, qLDiagInv, rownnz, rowadr, colind)
    # (14c) eliminates lambda_h: Lam lambda_h = -Jh M^-1 [B, Jc', -h] [x; 1] - Jdot_h v with
    # Lam = Jh M^-1 Jh' = W[:, :nh]: S = Lam^-1 [-W[:, nh:], -Jdot_h v]
    np.dot(Jh, Y, W)
    for r in range(nh):
        for j in range(nf):
            S[r, j] = -W[r, nh + j]
        S[r, nf] = -Jh_dot_v[r]
    if _cholesky_solve(W[:, :nh], S, n + 2) != 0:
        return 1
    # dv = G [x; 1; 1], G = (M^-1 Jh') S + [M^-1 [B, Jc', -h], 0]
    for i in range(nv):
        for r in range(nh):
            Yh[i, r] = Y[i, r]
    np.dot(Yh, S, G)
    for i in range(nv):
        for j in range(nf):
            G[i, j] += Y[i, nh + j]
    # the model's source rows as affine functions of x: SG = [J_com; Jc] G
    for i in range(nv):
        for a in range(3):
            src[a, i] = J_com[a, i]
        for r in range(12):
            src[3 + r, i] = Jc[r, i]
    np.dot(src, G, SG)
    # the cost (14a): rows sqrt(w) (a x + a0 - b) stacked into (Aw, rw)
    if na > 0:
        sw = math.sqrt(wts[0])
        for i in range(nv):
            for j in range(n):
                Aw[i, j] = sw * G[i, j]
            rw[i] = sw * (G[i, n] + G[i, n + 1])
    nsrc = 15 + nv
    for t in range(nt):  # task rows c0 (S[i0] + c1 S[i1])
        for q in range(2):
            idx = ri[t, q]
            dst = row if q == 0 else tmp
            if idx < 0:
                continue
            if idx < 15:
                for j in range(n + 2):
                    dst[j] = SG[idx, j]
            elif idx < nsrc:
                for j in range(n + 2):
                    dst[j] = G[idx - 15, j]
            else:
                dr = tdense[idx - nsrc]
                for j in range(n + 2):
                    dst[j] = 0.0
                for i in range(nv):
                    if dr[i] != 0.0:
                        for j in range(n + 2):
                            dst[j] += dr[i] * G[i, j]
        c0, c1 = rf[t, 0], rf[t, 1]
        if ri[t, 1] >= 0:
            for j in range(n + 2):
                row[j] = c0 * (row[j] + c1 * tmp[j])
        else:
            for j in range(n + 2):
                row[j] = c0 * row[j]
        sw = math.sqrt(rf[t, 3])
        for j in range(n):
            Aw[na + t, j] = sw * row[j]
        rw[na + t] = sw * (row[n] + row[n + 1] - rf[t, 2])
    sw = math.sqrt(wts[1])
    for r in range(n3):  # soft contact (14d): Jc dv + Jdot_c v = eps
        a = SG[3 + rows[r]]
        for j in range(n):
            Aw[na + nt + r, j] = sw * a[j]
        rw[na + nt + r] = sw * (a[n] + a[n + 1] + Jc_dot_v[rows[r]])
    np.dot(Aw.T, Aw, P)
    np.dot(Aw.T, rw, c)
    # torque / force magnitudes and their change from the previous tick (diagonal terms)
    for i in range(n):
        P[i, i] += wts[2] if i < nu else wts[3]
    for i in range(nu):
        c[i] -= wts[4] * u_prev[i]
    for r in range(n3):
        c[nu + r] -= wts[5] * lam_prev[rows[r]]
    # moments of the contact forces (the ALIP's u of (1) about its contact point)
    if nmom > 0 and wts[6] > 0.0:
        for q in range(nmom):
            for r in range(n3):
                a = moment_rows[q, rows[r]]
                if a != 0.0:
                    wa = wts[6] * a
                    c[nu + r] -= wa * moment_target[q]
                    for r2 in range(n3):
                        P[nu + r, nu + r2] += wa * moment_rows[q, rows[r2]]
    for i in range(n):  # exactly symmetric
        for j in range(i):
            P[i, j] = P[j, i]
    return 0
