"""Convex decomposition of the steppability mask (Section VI-B): contours with holes, an
approximate convex decomposition after Lien and Amato [18], the whittling algorithm
(Algorithm 1) with the MakeCut solver on the unit circle (Eq. (27), Algorithm 2).

Coordinates here are pixel coordinates (x = column, y = row) of the map image, which a
translation and a scale map to world xy without a flip, so counter-clockwise stays
counter-clockwise. The decomposition cuts the raster itself: a cut is a 4-connected line of
cleared cells, which splits an 8-connected region and can never leave the safe set.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import cv2
import numpy as np

from runtime.geometry import signed_area

_RAY_STEP_PX = 0.5


# --- small polygon helpers (vectorised over vertices) ----------------------------------------

def _next(a: np.ndarray) -> np.ndarray:
    """The array shifted by one along axis 0, cyclically (a cheaper np.roll(a, -1, 0))."""
    return np.concatenate((a[1:], a[:1]))


def ccw(poly: np.ndarray) -> np.ndarray:
    """The same polygon with counter-clockwise vertex order."""
    return poly[::-1].copy() if signed_area(poly) < 0.0 else poly


def convex_hull(points: np.ndarray) -> np.ndarray:
    """Counter-clockwise convex hull (k, 2) of 2D points."""
    hull = cv2.convexHull(np.ascontiguousarray(points, dtype=np.float32)).reshape(-1, 2)
    return ccw(hull.astype(np.float64))


def inward_edges(poly: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit inward normals n (k, 2) of the edges of a CCW convex polygon and offsets c (k,),
    so that the polygon is {x : n x >= c}."""
    e = _next(poly) - poly
    n = e[:, ::-1] * np.array([-1.0, 1.0])
    n /= np.maximum(np.sqrt(np.einsum("ij,ij->i", n, n)), 1e-300)[:, None]
    return n, np.einsum("ij,ij->i", n, poly)


def depth_inside(poly: np.ndarray, pts: np.ndarray,
                 edges: tuple[np.ndarray, np.ndarray] | None = None
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Signed distance of each point to the boundary of a CCW convex polygon (positive inside)
    and the index of the closest edge."""
    n, c = edges if edges is not None else inward_edges(poly)
    d = pts @ n.T - c[None, :]
    k = np.argmin(d, axis=1)
    return d[np.arange(len(pts)), k], k


def clip_halfplane(poly: np.ndarray, a: np.ndarray, c: float) -> np.ndarray:
    """Intersection of a convex polygon with {x : a.x >= c} (one Sutherland-Hodgman pass)."""
    s = poly @ a - c
    inside = s >= -1e-12
    if inside.all():
        return poly
    if not inside.any():
        return poly[:0]
    s_next = _next(s)
    p_next = _next(poly)
    crossing = inside != _next(inside)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(crossing, s / (s - s_next), 0.0)
    inter = poly + t[:, None] * (p_next - poly)
    slots = np.stack((poly, inter), axis=1)                    # (k, 2, 2)
    keep = np.stack((inside, crossing), axis=1)                # (k, 2)
    out = slots[keep]
    if len(out) > 1:
        step = np.linalg.norm(out - _next(out), axis=1)
        out = out[step > 1e-9] if np.any(step > 1e-9) else out[:1]
    return out


# --- MakeCut (Eq. (27), Algorithm 2) ----------------------------------------------------------

def make_cut(vertices: np.ndarray, vi: np.ndarray, a0: np.ndarray, alpha: float = 0.5,
             beta: float = 0.5, eps: float = 1e-6, max_iters: int = 50) -> np.ndarray:
    """Unit a minimising f(a) = sum_j max(a.(v_i - v_j), 0)^2 (Eq. (27)) on the unit circle.

    f penalises the vertices with a.v_j < a.v_i, so the kept half-plane is
    {x : a.(x - v_i) >= 0} and f sums the squared depths of the vertices it cuts away: the
    minimiser keeps as much of V as possible. (The paper writes H = {a.(x - v_i) <= 0}, which
    we read with its outward normal -a; with the literal sign f would penalise kept vertices.)
    Algorithm 2: rotate a by theta t, theta = grad f x a (the
    gradient's component tangent to the circle as a signed angle), backtracking t <- beta t
    while the cost rises, until |theta| <= eps; a is re-normalised each step. The first trial
    angle is the smaller of alpha and the Newton step along the circle (f is piecewise
    quadratic, so this converges in a few iterations instead of hundreds). The problem is
    scaled so that eps is relative to the polygon's size.
    """
    ax, ay = _make_cut_py(np.asarray(vertices, dtype=np.float64).tolist(), float(vi[0]),
                          float(vi[1]), float(a0[0]), float(a0[1]), alpha, beta, eps, max_iters)
    return np.array([ax, ay])


def _rotate_step(cost: Callable[[float, float], float], ax: float, ay: float, f: float,
                 theta: float, curv: float, alpha: float,
                 beta: float) -> tuple[float, float, float, bool] | None:
    """One rotation of the cut normal along the unit circle (Algorithm 2): a Newton step capped
    at alpha, backtracked by beta while the cost rises. Returns the new normal, its cost and
    whether the rotation was negligible; None when no decreasing rotation was found."""
    step = alpha if curv <= 0.0 else min(alpha, abs(theta) / curv)
    t = step / abs(theta)
    for _ in range(40):                        # backtracking: while f(Rotate) > f(x)
        ang = theta * t
        ca, sa = math.cos(ang), math.sin(ang)
        nx, ny = ca * ax - sa * ay, sa * ax + ca * ay
        fn = cost(nx, ny)
        if fn <= f:
            norm = math.hypot(nx, ny)
            return nx / norm, ny / norm, fn, abs(theta * t) < 1e-9
        t *= beta
    return None


def _descend(cost: Callable[[float, float], float],
             gradient: Callable[[float, float], tuple[float, float, float]], ax: float,
             ay: float, alpha: float, beta: float, eps: float,
             max_iters: int) -> tuple[float, float]:
    """Algorithm 2's iterations from the unit normal (ax, ay): ``gradient`` gives grad f and
    2 sum_active (w.a_perp)^2 (the Gauss-Newton part of the curvature along the circle)."""
    f = cost(ax, ay)
    for _ in range(max_iters):
        gx, gy, curv_h = gradient(ax, ay)
        theta = gx * ay - gy * ax              # (g - a<g,a>) x a == g x a in 2D
        if abs(theta) <= eps:
            break
        # curvature of f along the circle at a: 2 sum_active (w.a_perp)^2 - a.g
        curv = curv_h - (gx * ax + gy * ay)
        moved = _rotate_step(cost, ax, ay, f, theta, curv, alpha, beta)
        if moved is None:
            break
        ax, ay, f, converged = moved
        if converged:
            break
    return ax, ay


_PY_MAX_POINTS = 48      # above this many vertices the numpy variants are faster


def _make_cut_py(vl: list[list[float]], xi: float, yi: float, a0x: float, a0y: float,
                 alpha: float, beta: float, eps: float, max_iters: int) -> tuple[float, float]:
    """make_cut on plain lists: tens of points, where Python arithmetic beats numpy calls."""
    if len(vl) > _PY_MAX_POINTS:
        return _make_cut_np(np.asarray(vl), xi, yi, a0x, a0y, alpha, beta, eps, max_iters)
    pts = [(xi - x, yi - y) for x, y in vl if (xi - x) ** 2 + (yi - y) ** 2 > 1e-18]
    norm0 = math.hypot(a0x, a0y)
    ax, ay = a0x / norm0, a0y / norm0
    if not pts:
        return ax, ay
    scale = 1.0 / max(max(abs(px), abs(py)) for px, py in pts)
    pts = [(px * scale, py * scale) for px, py in pts]   # scale-free cost: |w| <= sqrt(2)

    def cost(cx: float, cy: float) -> float:
        acc = 0.0
        for px, py in pts:
            m = px * cx + py * cy
            if m > 0.0:
                acc += m * m
        return acc

    def gradient(cx: float, cy: float) -> tuple[float, float, float]:
        gx = gy = curv_h = 0.0
        for px, py in pts:
            m = px * cx + py * cy
            if m > 0.0:
                gx += m * px
                gy += m * py
                perp = -px * cy + py * cx
                curv_h += perp * perp
        return 2.0 * gx, 2.0 * gy, 2.0 * curv_h

    return _descend(cost, gradient, ax, ay, alpha, beta, eps, max_iters)


def _make_cut_np(v: np.ndarray, xi: float, yi: float, a0x: float, a0y: float, alpha: float,
                 beta: float, eps: float, max_iters: int) -> tuple[float, float]:
    """The same solver (Algorithm 2) vectorised over the vertices, for large polygons."""
    w = np.array([xi, yi]) - v
    w = w[np.einsum("ij,ij->i", w, w) > 1e-18]
    norm0 = math.hypot(a0x, a0y)
    ax, ay = a0x / norm0, a0y / norm0
    if len(w) == 0:
        return ax, ay
    w = w / np.max(np.abs(w))
    wx, wy = w[:, 0], w[:, 1]

    def cost(cx: float, cy: float) -> float:
        m = np.maximum(wx * cx + wy * cy, 0.0)
        return float(m @ m)

    def gradient(cx: float, cy: float) -> tuple[float, float, float]:
        proj = wx * cx + wy * cy
        m = np.maximum(proj, 0.0)
        perp = -wx * cy + wy * cx
        return (2.0 * float(m @ wx), 2.0 * float(m @ wy),
                2.0 * float((perp * perp) @ (proj > 0.0)))

    return _descend(cost, gradient, ax, ay, alpha, beta, eps, max_iters)


# --- whittling (Algorithm 1) ------------------------------------------------------------------

# Algorithm 1 makes a handful of cuts on polygons of 5-30 vertices: at that size plain Python
# arithmetic beats numpy's per-call overhead, so its inner geometry works on lists of floats.

def _edges_py(poly: list[list[float]]) -> list[tuple[float, float, float]]:
    """Inward unit normal and offset (n, c) of each edge of a CCW convex polygon: n.x >= c."""
    out = []
    m = len(poly)
    for j in range(m):
        x0, y0 = poly[j]
        x1, y1 = poly[(j + 1) % m]
        ex, ey = x1 - x0, y1 - y0
        length = math.hypot(ex, ey)
        if length > 1e-12:
            nx, ny = -ey / length, ex / length
            out.append((nx, ny, nx * x0 + ny * y0))
    return out


def _depth_py(edges: list[tuple[float, float, float]], x: float, y: float) -> tuple[float, int]:
    """Depth of (x, y) below the boundary (positive inside) and the closest edge's index."""
    best, k_best = math.inf, 0
    for k, (nx, ny, c) in enumerate(edges):
        d = nx * x + ny * y - c
        if d < best:
            best, k_best = d, k
    return best, k_best


def _clip_py(poly: list[list[float]], ax: float, ay: float, c: float) -> list[list[float]]:
    """Sutherland-Hodgman with one half-plane a.x >= c on a convex polygon."""
    m = len(poly)
    s = [ax * x + ay * y - c for x, y in poly]
    out: list[list[float]] = []
    for j in range(m):
        j1 = (j + 1) % m
        in0, in1 = s[j] >= -1e-12, s[j1] >= -1e-12
        if in0:
            out.append(poly[j])
        if in0 != in1:
            t = s[j] / (s[j] - s[j1])
            x0, y0 = poly[j]
            x1, y1 = poly[j1]
            out.append([x0 + t * (x1 - x0), y0 + t * (y1 - y0)])
    dedup = [q for j, q in enumerate(out)
             if abs(q[0] - out[j - 1][0]) + abs(q[1] - out[j - 1][1]) > 1e-9]
    return dedup if len(dedup) >= 1 or not out else out[:1]


def _intrusions_py(edges: list[tuple[float, float, float]], vl: list[list[float]],
                   tol: float) -> tuple[list[float] | None, float]:
    """The deepest point (if deeper than tol) where an edge of the original polygon passes
    through the convex polygon given by its inward edges (Cyrus-Beck clipping per edge)."""
    if len(vl) * len(edges) > _PY_MAX_POINTS * 8:
        return _intrusions_np(edges, vl, tol)
    best, best_d = None, tol
    m = len(vl)
    for j in range(m):
        sx, sy = vl[j]
        ex, ey = vl[(j + 1) % m]
        dx, dy = ex - sx, ey - sy
        t_lo, t_hi = 0.0, 1.0
        for nx, ny, c in edges:
            num = nx * sx + ny * sy - c
            den = nx * dx + ny * dy
            if abs(den) <= 1e-12:
                if num < 0.0:
                    t_hi = -1.0
                    break
            elif den > 0.0:
                t_lo = max(t_lo, -num / den)
            else:
                t_hi = min(t_hi, -num / den)
            if t_hi <= t_lo:
                break
        if t_hi <= t_lo + 1e-9:
            continue
        for fr in (0.25, 0.5, 0.75):
            t = t_lo + fr * (t_hi - t_lo)
            px, py = sx + t * dx, sy + t * dy
            d, _ = _depth_py(edges, px, py)
            if d > best_d:
                best, best_d = [px, py], d
    return best, best_d


def _intrusions_np(edges: list[tuple[float, float, float]], vl: list[list[float]],
                   tol: float) -> tuple[list[float] | None, float]:
    """_intrusions_py vectorised over (polygon edge, half-plane) pairs, for large polygons."""
    e = np.asarray(edges)
    s = np.asarray(vl)
    d = np.concatenate((s[1:], s[:1])) - s
    num = s @ e[:, :2].T - e[:, 2]                   # (m, k): n.s - c
    den = d @ e[:, :2].T                             # n.d
    with np.errstate(divide="ignore", invalid="ignore"):
        bound = -num / den
    t_lo = np.max(np.where(den > 1e-12, bound, 0.0), axis=1, initial=0.0)
    t_hi = np.min(np.where(den < -1e-12, bound, 1.0), axis=1, initial=1.0)
    blocked = np.any((np.abs(den) <= 1e-12) & (num < 0.0), axis=1)
    ok = (t_hi > t_lo + 1e-9) & ~blocked
    if not ok.any():
        return None, tol
    fr = np.array([0.25, 0.5, 0.75])
    ts = t_lo[ok, None] + fr[None, :] * (t_hi - t_lo)[ok, None]
    pts = (s[ok, None, :] + ts[..., None] * d[ok, None, :]).reshape(-1, 2)
    depth = (pts @ e[:, :2].T - e[:, 2]).min(axis=1)
    j = int(np.argmax(depth))
    if depth[j] <= tol:
        return None, tol
    return pts[j].tolist(), float(depth[j])


def whittle(vertices: np.ndarray, tol: float = 0.25, alpha: float = 0.5, beta: float = 0.5,
            eps: float = 1e-6, max_iters: int = 50) -> np.ndarray:
    """Algorithm 1: a convex inner approximation (CCW) of a nearly convex simple polygon."""
    poly, _ = _whittle(vertices, tol, alpha, beta, eps, max_iters)
    assert poly is not None          # no budget: always a polygon
    return poly


def _whittle(vertices: np.ndarray, tol: float, alpha: float, beta: float, eps: float,
             max_iters: int, budget: int | None = None) -> tuple[np.ndarray | None, int]:
    """Algorithm 1: a convex inner approximation (CCW) of a nearly convex simple polygon.

    P starts as the convex hull of V; the vertices are visited innermost first (sorted by
    depth below the boundary of P) and each one still deeper than `tol` inside P triggers a
    MakeCut half-plane with the closest face's inward normal as the initial guess. A last pass
    also cuts where an original edge crosses P's interior between two outside vertices.
    Returns the polygon and the number of cuts made; the polygon is None when more than
    `budget` cuts would be needed (a bounded worst case, and deterministic, unlike a timer).
    """
    v = ccw(np.asarray(vertices, dtype=np.float64))
    hull = convex_hull(v)
    if len(hull) < 3:
        return hull, 0
    poly = hull.tolist()
    edges = _edges_py(poly)
    vl = v.tolist()
    depth = [_depth_py(edges, x, y)[0] for x, y in vl]
    if max(depth) <= tol:
        return hull, 0  # every vertex on the hull: V is convex up to tol, nothing to whittle
    cuts = 0
    for i in sorted(range(len(vl)), key=lambda j: -depth[j]):   # innermost first
        if depth[i] <= tol:
            break
        xi, yi = vl[i]
        d_now, k = _depth_py(edges, xi, yi)
        if d_now <= tol:
            continue
        if budget is not None and cuts >= budget:
            return None, cuts
        ax, ay = _make_cut_py(vl, xi, yi, edges[k][0], edges[k][1], alpha, beta, eps,
                              max_iters)
        poly = _clip_py(poly, ax, ay, ax * xi + ay * yi)
        cuts += 1
        if len(poly) < 3:
            return np.array(poly, dtype=np.float64).reshape(-1, 2), cuts
        edges = _edges_py(poly)
    for _ in range(2 * len(v) + 1):
        w, _ = _intrusions_py(edges, vl, tol)
        if w is None:
            break
        if budget is not None and cuts >= budget:
            return None, cuts
        _, k = _depth_py(edges, w[0], w[1])
        ax, ay = _make_cut_py(vl, w[0], w[1], edges[k][0], edges[k][1], alpha, beta, eps,
                              max_iters)
        poly = _clip_py(poly, ax, ay, ax * w[0] + ay * w[1])
        cuts += 1
        if len(poly) < 3:
            break
        edges = _edges_py(poly)
    return np.array(poly, dtype=np.float64).reshape(-1, 2), cuts


# --- approximate convex decomposition on the raster -----------------------------------------

@dataclass
class _Piece:
    mask: np.ndarray        # uint8 ROI with a 1-px zero border
    x0: int                 # image column of the ROI's column 0
    y0: int                 # image row of the ROI's row 0


def _pieces(mask: np.ndarray, x0: int, y0: int, min_px: float) -> list[_Piece]:
    """8-connected components of `mask` with at least `min_px` cells, each in its own ROI."""
    _, labels, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
    out = []
    # ascending area: the work stack pops the largest region first, so budgets spent on
    # a frame go to the footholds that matter most
    for lab in (np.argsort(stats[1:, cv2.CC_STAT_AREA], kind="stable") + 1).tolist():
        x, y, w, h, area = stats[lab]
        if area < min_px:
            continue
        roi = np.zeros((h + 2, w + 2), np.uint8)
        roi[1:-1, 1:-1] = labels[y:y + h, x:x + w] == lab
        out.append(_Piece(roi, x0 + x - 1, y0 + y - 1))
    return out


def _ray_samples(mask: np.ndarray, p: np.ndarray, dirs: np.ndarray) -> tuple[np.ndarray,
                                                                              np.ndarray]:
    """Sample `mask` along rays p + t u (t in half-pixel steps); outside the ROI reads 0."""
    tmax = float(np.hypot(*mask.shape)) + 2.0
    ts = np.arange(0.0, tmax, _RAY_STEP_PX)
    pts = p[None, None, :] + ts[None, :, None] * dirs[:, None, :]
    ix = np.rint(pts[..., 0]).astype(np.int64)
    iy = np.rint(pts[..., 1]).astype(np.int64)
    inb = (ix >= 0) & (ix < mask.shape[1]) & (iy >= 0) & (iy < mask.shape[0])
    vals = np.zeros(ix.shape, dtype=bool)
    vals[inb] = mask[iy[inb], ix[inb]] > 0
    return ts, vals


def _exit_after_fg(vals: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per ray: index of the first foreground sample and of the first background sample after
    it (len if none)."""
    n = vals.shape[1]
    has_fg = vals.any(axis=1)
    first_fg = np.where(has_fg, np.argmax(vals, axis=1), n)
    seen = np.cumsum(vals, axis=1) > 0
    after = seen & ~vals
    exit_idx = np.where(after.any(axis=1), np.argmax(after, axis=1), n - 1)
    return first_fg, exit_idx


def _cut_hole(mask: np.ndarray, hole: np.ndarray) -> bool:
    """Resolve a hole (Lien-Amato: holes always need resolving) with the shortest straight cut
    through its centroid that reaches the outer boundary on both sides."""
    c = hole.reshape(-1, 2).astype(np.float64).mean(axis=0)
    ang = np.linspace(0.0, np.pi, 8, endpoint=False)
    u = np.column_stack((np.cos(ang), np.sin(ang)))
    dirs = np.concatenate((u, -u))
    ts, vals = _ray_samples(mask, c, dirs)
    first_fg, exit_idx = _exit_after_fg(vals)
    n = vals.shape[1]
    ok = first_fg < n
    fg_len = np.where(ok, ts[np.minimum(exit_idx, n - 1)] - ts[np.minimum(first_fg, n - 1)],
                      np.inf)
    total = fg_len[:8] + fg_len[8:]
    best = int(np.argmin(total))
    if not np.isfinite(total[best]):
        return False
    ends = []
    for j in (best, best + 8):
        q = c + ts[exit_idx[j]] * dirs[j]
        ends.append((round(q[0]), round(q[1])))
    cv2.line(mask, ends[0], ends[1], 0, thickness=1, lineType=cv2.LINE_4)
    return True


def _concavity(poly: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Straight-line concavity of every vertex: its distance to the hull bridge spanning its
    pocket (Lien-Amato SL-concavity), and that bridge's direction vector per vertex."""
    hull_idx = np.sort(cv2.convexHull(poly.astype(np.float32), returnPoints=False).ravel())
    edge = np.searchsorted(hull_idx, np.arange(len(poly)), side="right") - 1
    a = poly[hull_idx[edge]]
    b = poly[hull_idx[(edge + 1) % len(hull_idx)]]
    ab = b - a
    ap = poly - a
    length = np.maximum(np.hypot(ab[:, 0], ab[:, 1]), 1e-12)
    depth = np.abs(ab[:, 0] * ap[:, 1] - ab[:, 1] * ap[:, 0]) / length
    return depth, ab


def _cut_notch(mask: np.ndarray, poly: np.ndarray, i: int, bridge: np.ndarray) -> bool:
    """Resolve the deepest notch with the shortest of four straight cuts from it: along either
    incident edge, their bisector, or across the pocket's bridge."""
    p = poly[i]
    prev_v, next_v = poly[i - 1], poly[(i + 1) % len(poly)]
    cand = [p - prev_v, p - next_v]
    cand.append(cand[0] / max(np.linalg.norm(cand[0]), 1e-12)
                + cand[1] / max(np.linalg.norm(cand[1]), 1e-12))
    nb = np.array([-bridge[1], bridge[0]])
    cand.append(nb)
    cand.append(-nb)
    dirs = np.array(cand, dtype=np.float64)
    norms = np.linalg.norm(dirs, axis=1)
    dirs = dirs[norms > 1e-9] / norms[norms > 1e-9, None]
    ts, vals = _ray_samples(mask, p, dirs)
    n = vals.shape[1]
    # exit: first background sample; a usable cut goes through foreground for >= 1.5 px
    bg = ~vals
    bg[:, 0] = False
    exit_idx = np.where(bg.any(axis=1), np.argmax(bg, axis=1), n - 1)
    length = ts[exit_idx]
    length = np.where(length >= 1.5, length, np.inf)
    best = int(np.argmin(length))
    if not np.isfinite(length[best]):
        return False
    q = p + length[best] * dirs[best]
    cv2.line(mask, (int(p[0]), int(p[1])), (round(q[0]), round(q[1])), 0,
             thickness=1, lineType=cv2.LINE_4)
    return True


def _leaves_region(poly: np.ndarray, mask: np.ndarray, margin: float = 0.5) -> bool:
    """True when a cell centre at least `margin` px inside the convex polygon is not in mask.

    The guard behind Algorithm 1: MakeCut keeps the side with more vertices, which for a
    pocket with a narrow mouth can be the pocket itself (outside the region). Only the empty
    cells of the polygon's bounding box are tested, one matrix product for all of them.
    """
    pl = poly.tolist()
    xs = [q[0] for q in pl]
    ys = [q[1] for q in pl]
    x0, x1 = max(math.ceil(min(xs)), 0), min(math.floor(max(xs)), mask.shape[1] - 1)
    y0, y1 = max(math.ceil(min(ys)), 0), min(math.floor(max(ys)), mask.shape[0] - 1)
    if x1 < x0 or y1 < y0:
        return False
    rows, cols = np.nonzero(mask[y0:y1 + 1, x0:x1 + 1] == 0)
    if rows.size == 0:
        return False
    edges = np.array(_edges_py(pl))
    if edges.size == 0:
        return False
    depth = (np.multiply.outer(cols + float(x0), edges[:, 0])
             + np.multiply.outer(rows + float(y0), edges[:, 1]) - edges[:, 2]).min(axis=1)
    return bool((depth >= margin).any())


def approximate_convex_decomposition(mask: np.ndarray, resolution: float,
                                     concavity_limit_m: float, min_area_m2: float,
                                     epsilon_px: float = 0.5, max_cuts: int = 24,
                                     whittle_args: tuple[float, float, float, float, int]
                                     | None = None, max_whittle_cuts: int | None = None,
                                     stats: dict[str, int] | None = None
                                     ) -> tuple[list[np.ndarray], int]:
    """ACD of the safe regions [18]: split until every piece is d-approximately convex.

    Components come from the mask; a piece with holes is cut through its largest hole first,
    then a piece whose deepest notch (distance to its hull bridge) exceeds d is cut from that
    notch. Pieces under `min_area_m2` are dropped. Returns simplified outer contours in pixel
    coordinates (CCW) and the number of cuts made; after `max_cuts` the remaining pieces are
    returned as they are. With `whittle_args` = (tol, alpha, beta, eps, max_iters) each piece
    is whittled (Algorithm 1) at once and checked against its own cells: a polygon that leaves
    them sends the piece back for a cut at its deepest notch (or is dropped when none is left);
    whittling shares a per-frame budget of `max_whittle_cuts`, past which pieces are dropped.
    `stats`, if given, receives the counts acd_cuts, whittle_cuts and dropped.
    """
    mask_u8 = (np.asarray(mask) > 0).astype(np.uint8)
    min_px = min_area_m2 / (resolution * resolution)
    limit_px = concavity_limit_m / resolution
    stack = _pieces(mask_u8, 0, 0, min_px)
    out: list[np.ndarray] = []
    cuts = 0
    whittle_cuts = 0
    dropped = 0
    while stack:  # loop over pieces and cuts, each whole-array
        piece = stack.pop()
        contours, hier = cv2.findContours(piece.mask, cv2.RETR_CCOMP, cv2.CHAIN_APPROX_SIMPLE)
        if not contours:
            continue
        parent = hier.reshape(-1, 4)[:, 3].tolist()
        outer_idx = [k for k, par in enumerate(parent) if par < 0]
        if len(outer_idx) != 1:     # a cut left several parts: relabel them
            stack.extend(_pieces(piece.mask, piece.x0, piece.y0, min_px))
            continue
        oi = outer_idx[0]
        outer = contours[oi].reshape(-1, 2)
        holes = [contours[k] for k, par in enumerate(parent) if par == oi]
        area = cv2.contourArea(outer)
        if holes:
            area -= sum(cv2.contourArea(h) for h in holes)
        if area < min_px:
            continue
        poly = outer.astype(np.float64)
        if epsilon_px > 0.0 and len(outer) > 3:
            poly = cv2.approxPolyDP(outer, epsilon_px, True).reshape(-1, 2).astype(np.float64)
        if len(poly) < 3:
            continue
        if cuts < max_cuts and holes:
            hole = max(holes, key=lambda h: abs(cv2.contourArea(h)) + len(h))
            if _cut_hole(piece.mask, hole):
                cuts += 1
                stack.extend(_pieces(piece.mask, piece.x0, piece.y0, min_px))
                continue
        conc, bridges = _concavity(poly)
        i = int(np.argmax(conc))
        if cuts < max_cuts and conc[i] > limit_px and \
                _cut_notch(piece.mask, poly, i, bridges[i]):
            cuts += 1
            stack.extend(_pieces(piece.mask, piece.x0, piece.y0, min_px))
            continue
        if abs(signed_area(poly)) < min_px:
            continue
        if whittle_args is not None:
            tol, alpha, beta, eps, iters = whittle_args
            budget = None if max_whittle_cuts is None else max_whittle_cuts - whittle_cuts
            convex, made = _whittle(poly, tol, alpha, beta, eps, iters, budget)
            whittle_cuts += made
            if convex is None:
                dropped += 1
                continue
            # checked even without cuts: the contour of a thin (1-2 px) region runs out and
            # back along itself, so its hull can span cells that are not in the region
            if len(convex) >= 3 and _leaves_region(convex, piece.mask):
                if cuts < max_cuts and conc[i] > 0.0 and \
                        _cut_notch(piece.mask, poly, i, bridges[i]):
                    cuts += 1
                    stack.extend(_pieces(piece.mask, piece.x0, piece.y0, min_px))
                else:
                    dropped += 1        # no cut left: drop it rather than leave the region
                continue
            poly = convex
        out.append(ccw(poly + np.array([piece.x0, piece.y0], dtype=np.float64)))
    if stats is not None:
        stats.update(acd_cuts=cuts, whittle_cuts=whittle_cuts, dropped=dropped)
    return out, cuts


def convex_decomposition(mask: np.ndarray, resolution: float, concavity_limit_m: float,
                         min_area_m2: float, min_foothold_area_m2: float,
                         epsilon_px: float = 0.5, whittle_tol_px: float = 0.25,
                         max_cuts: int = 24, max_polygons: int = 32, alpha: float = 0.5,
                         beta: float = 0.5, eps: float = 1e-6, max_iters: int = 50,
                         max_whittle_cuts: int | None = 64,
                         stats: dict[str, int] | None = None) -> list[np.ndarray]:
    """Mask -> convex CCW polygons in pixel coordinates: ACD, area filter, whittling.

    The largest `max_polygons` survive (MPFC's mixed-integer cost grows with their number).
    """
    pieces, _ = approximate_convex_decomposition(
        mask, resolution, concavity_limit_m, min_area_m2, epsilon_px, max_cuts,
        (whittle_tol_px, alpha, beta, eps, max_iters), max_whittle_cuts, stats)
    min_px = min_foothold_area_m2 / (resolution * resolution)
    areas = [signed_area(p) for p in pieces]
    keep = sorted((a, k) for k, a in enumerate(areas) if a >= max(min_px, 1e-9))[::-1]
    return [pieces[k] for _, k in keep[:max_polygons]]
