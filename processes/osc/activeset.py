"""Exact solution of the OSC's small QP by a dual active-set method, compiled (numba).

    min 1/2 x'Px + c'x   s.t.   lo <= x <= hi,   A x <= b        (P symmetric positive definite)

Goldfarb and Idnani's dual method (Math. Programming 27, 1983): start at the unconstrained
minimiser -P^-1 c (dual feasible: no multipliers), then repeatedly add the most violated
constraint, moving x along the direction that keeps every active constraint satisfied and
dropping an active constraint whose multiplier would turn negative. Each step keeps the
multipliers >= 0 and raises the cost, so it ends at the optimum after finitely many steps
(a handful here: the optimum of the OSC's QP has 0-12 active constraints). Directions use
the Cholesky factor P = R'R and an orthonormal basis of R^-T [a_j, j active] (Gram-Schmidt,
twice), as the method's textbook implementation does.

The result is returned only when it satisfies the KKT conditions of the whole QP, checked
explicitly: every constraint within ``tol``, every multiplier >= -``tol``, and the
stationarity residual P x + c + sum_j lam_j a_j at rounding level. Anything else (cycling on
a degenerate vertex, an infeasible set of constraints, a factor that is not positive
definite) returns status 0 and the caller decides (piqp).
"""

from __future__ import annotations

import math

import numba
import numpy as np

_jit = numba.njit(cache=True, nogil=True)


@_jit
def cholesky_upper(P: np.ndarray, R: np.ndarray) -> bool:
    """The upper Cholesky factor of symmetric ``P`` (its upper triangle read), P = R'R, into
    the upper triangle of ``R`` (which may be ``P`` itself: each entry is read before it is
    written). False when P is not positive definite."""
    n = P.shape[0]
    for j in range(n):
        d = P[j, j]
        for k in range(j):
            d -= R[k, j] * R[k, j]
        if not d > 0.0:
            return False
        d = math.sqrt(d)
        R[j, j] = d
        for i in range(j + 1, n):
            s = P[j, i]
            for k in range(j):
                s -= R[k, j] * R[k, i]
            R[j, i] = s / d
    return True


@_jit
def _viol(j: int, x: np.ndarray, lo: np.ndarray, hi: np.ndarray, A: np.ndarray,
          b: np.ndarray) -> float:
    """a_j x - b_j of constraint j (0 <= j < n: x_j >= lo_j; n <= j < 2n: x_j <= hi_j; then
    the rows of A x <= b); > 0 means violated."""
    n = x.size
    if j < n:
        return lo[j] - x[j]
    if j < 2 * n:
        return x[j - n] - hi[j - n]
    r = j - 2 * n
    s = 0.0
    for i in range(n):
        s += A[r, i] * x[i]
    return s - b[r]


@_jit
def _violations(x: np.ndarray, lo: np.ndarray, hi: np.ndarray, A: np.ndarray, b: np.ndarray,
                out: np.ndarray) -> None:
    """``_viol`` of every constraint at once, into ``out`` (2 n + rows of A)."""
    n = x.size
    for j in range(n):
        out[j] = lo[j] - x[j]
        out[n + j] = x[j] - hi[j]
    for r in range(A.shape[0]):
        s = 0.0
        for i in range(n):
            s += A[r, i] * x[i]
        out[2 * n + r] = s - b[r]


@_jit
def _normal(j: int, n: int, A: np.ndarray, out: np.ndarray) -> None:
    """The normal a_j of constraint j (written as a_j x <= b_j)."""
    # explicit loops, here and below: slice assignments make numba compile far longer
    if j < 2 * n:
        for i in range(n):
            out[i] = 0.0
        out[j % n] = -1.0 if j < n else 1.0
    else:
        for i in range(n):
            out[i] = A[j - 2 * n, i]


@_jit
def _dot(a: np.ndarray, b: np.ndarray) -> float:
    """a . b (a loop: no BLAS call for vectors of ~20)."""
    s = 0.0
    for i in range(a.size):
        s += a[i] * b[i]
    return s


@_jit
def _rt_solve(R: np.ndarray, a: np.ndarray, out: np.ndarray) -> None:
    """out = R^-T a for upper triangular R (forward substitution)."""
    n = a.size
    for i in range(n):
        s = a[i]
        for k in range(i):
            s -= R[k, i] * out[k]
        out[i] = s / R[i, i]


@_jit
def _r_solve(R: np.ndarray, w: np.ndarray, out: np.ndarray) -> None:
    """out = R^-1 w for upper triangular R (back substitution)."""
    n = w.size
    for i in range(n - 1, -1, -1):
        s = w[i]
        for k in range(i + 1, n):
            s -= R[i, k] * out[k]
        out[i] = s / R[i, i]


@_jit
def _project(U: np.ndarray, m: int, q: np.ndarray, coef: np.ndarray, w: np.ndarray) -> None:
    """w = q minus its projection on the rows U[:m] (orthonormal), coef = U q; Gram-Schmidt
    twice, so w is orthogonal to working precision."""
    n = q.size
    for k in range(n):
        w[k] = q[k]
    for i in range(m):
        coef[i] = 0.0
    for _ in range(2):
        for i in range(m):
            s = _dot(U[i], w)
            coef[i] += s
            for k in range(n):
                w[k] -= s * U[i, k]


@_jit
def _refactor(Qa: np.ndarray, m: int, U: np.ndarray, T: np.ndarray, coef: np.ndarray,
              w: np.ndarray) -> bool:
    """QR of the columns Qa[:m] (stored as rows): Qa[j] = sum_i T[i, j] U[i]. False when a
    column is (numerically) dependent on the previous ones."""
    for j in range(m):
        _project(U, j, Qa[j], coef, w)
        nrm = math.sqrt(_dot(w, w))
        if not nrm > 1e-12 * math.sqrt(_dot(Qa[j], Qa[j])):
            return False
        for i in range(j):
            T[i, j] = coef[i]
        T[j, j] = nrm
        for k in range(w.size):
            U[j, k] = w[k] / nrm
    return True


@_jit
def solve_dual_active_set(P: np.ndarray, c: np.ndarray, lo: np.ndarray, hi: np.ndarray,
                          A: np.ndarray, b: np.ndarray, x: np.ndarray, lam: np.ndarray,
                          iwork: np.ndarray, work: np.ndarray, viol: np.ndarray, tol: float,
                          max_iter: int) -> tuple[int, int, int]:
    """Solve the QP above into ``x``; returns (status, steps, number of active constraints).

    status 1: ``x`` is the optimum, certified by the KKT conditions (``iwork[:m]`` are the
    active constraints' ids, numbered as in ``_viol``, ``lam[:m]`` their multipliers);
    0: not certified (see the module docstring). Scratch: ``work`` (4 n + 7, n), ``viol``
    (2 n + rows of A), ``iwork`` (n + len(viol)); n = len(x). Infinite bounds are allowed
    (never active).
    """
    n = x.size
    nc = 2 * n + A.shape[0]
    active = iwork[:n]
    flag = iwork[n : n + nc]  # 1: in the active set
    for j in range(nc):
        flag[j] = 0
    R = work[:n]
    U = work[n : 2 * n]
    Qa = work[2 * n : 3 * n]
    T = work[3 * n : 4 * n]
    vec = work[4 * n :]
    q, w, z, coef, r, a, g = vec[0], vec[1], vec[2], vec[3], vec[4], vec[5], vec[6]
    # Cholesky P = R'R (upper)
    if not cholesky_upper(P, R):
        return 0, 0, 0
    for j in range(n):
        for i in range(j):
            R[j, i] = 0.0
    # unconstrained minimiser x = -P^-1 c
    _rt_solve(R, c, w)
    _r_solve(R, w, x)
    for i in range(n):
        x[i] = -x[i]
    m = 0
    steps = 0
    while True:
        # the most violated constraint not in the active set
        _violations(x, lo, hi, A, b, viol)
        p = -1
        vmax = tol
        for j in range(nc):
            if viol[j] > vmax and flag[j] == 0:
                vmax = viol[j]
                p = j
        if p < 0:
            break
        if m >= n:
            return 0, steps, m
        _normal(p, n, A, a)
        _rt_solve(R, a, q)
        lam_p = 0.0
        while True:
            steps += 1
            if steps > max_iter:
                return 0, steps, m
            # primal direction z = -R^-1 w (w: R^-T a_p off the active normals), dual r
            _project(U, m, q, coef, w)
            for i in range(m - 1, -1, -1):
                s = coef[i]
                for k in range(i + 1, m):
                    s -= T[i, k] * r[k]
                r[i] = s / T[i, i]
            t1 = math.inf  # partial step: an active multiplier reaches zero
            kdrop = -1
            for i in range(m):
                if r[i] > 0.0:
                    ratio = lam[i] / r[i]
                    if ratio < t1:
                        t1 = ratio
                        kdrop = i
            ww = _dot(w, w)
            if ww > 1e-24 * _dot(q, q):
                _r_solve(R, w, z)
                t2 = _viol(p, x, lo, hi, A, b) / ww  # full step: constraint p satisfied
                t = min(t1, t2)
                for i in range(n):
                    x[i] -= t * z[i]
                for i in range(m):
                    lam[i] -= t * r[i]
                lam_p += t
                if t2 <= t1:  # add p to the active set (its column extends the QR)
                    nrm = math.sqrt(ww)
                    for i in range(m):
                        T[i, m] = coef[i]
                    T[m, m] = nrm
                    for k in range(n):
                        U[m, k] = w[k] / nrm
                        Qa[m, k] = q[k]
                    active[m] = p
                    flag[p] = 1
                    lam[m] = lam_p
                    m += 1
                    break
            else:  # a_p depends on the active normals: only the multipliers move
                if kdrop < 0:
                    return 0, steps, m  # the constraints cannot all hold
                for i in range(m):
                    lam[i] -= t1 * r[i]
                lam_p += t1
            # drop constraint kdrop and refactor the remaining columns
            flag[active[kdrop]] = 0
            for i in range(kdrop, m - 1):
                active[i] = active[i + 1]
                lam[i] = lam[i + 1]
                for k in range(n):
                    Qa[i, k] = Qa[i + 1, k]
            m -= 1
            if not _refactor(Qa, m, U, T, coef, w):
                return 0, steps, m
    # KKT certificate of the whole QP: primal and dual feasibility, stationarity (the scan
    # above found no constraint violated by more than tol; the active ones hold to rounding);
    # NaN fails no comparison below, so finiteness is checked first
    for i in range(n):
        if not math.isfinite(x[i]):
            return 0, steps, m
    _violations(x, lo, hi, A, b, viol)
    for j in range(nc):
        if viol[j] > tol:
            return 0, steps, m
    scale = 1.0  # the size of the terms summed: the residual's rounding-error scale
    for i in range(n):
        s = c[i]
        mag = abs(c[i])
        for k in range(n):
            s += P[i, k] * x[k]
            mag += abs(P[i, k] * x[k])
        g[i] = s
        scale = max(scale, mag)
    for i in range(m):
        if not lam[i] >= -tol:
            return 0, steps, m
        _normal(active[i], n, A, a)
        for k in range(n):
            g[k] += lam[i] * a[k]
    for k in range(n):
        if abs(g[k]) > 1e-9 * scale:
            return 0, steps, m
    return 1, steps, m
