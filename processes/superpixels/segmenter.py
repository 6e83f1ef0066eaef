"""QuadPiPS' superpixel planar regions (Asselmeier et al., Sections V-A, V-D, V-E) on our
elevation map: heights -> normals (eqs. (5)-(9)) -> health check and steppability -> modified
SLIC (eqs. (10)-(14)) with RANSAC-refined cluster normals -> projection of each cluster onto
its plane -> convex hull -> ``runtime.geometry.Foothold``. No LCM; the S3 process runs it in
S3's place (``params.method: superpixels``).

Where this departs from the paper, and why:

* The input is our elevation grid (rows along y, columns along x, NaN unknown), not the egocan
  floor image: a cell (u, v) is the point (u r, v r, z) (r the resolution), so eq. (6)'s
  pinhole terms become the constant spacing r. Normals come from the heights, first averaged
  over ``normal_window_px`` known cells (1: the paper's raw differences), because one forward
  difference of our maps' 1-3 cm noise at 2.5 cm cells tilts a flat cell by 20-50 deg.
* Unknown cells stay unknown: V-D-2's "initialise unseen floor to default ground" would put
  footholds over pits the map has not seen into; our map is centred on the robot and holds
  what the camera saw.
* The steppability label (V-B, a learned model) is replaced by a geometric rule: a cell is
  steppable when the heights of its 3 x 3 neighbourhood span less than ``max_step_m`` (a riser
  or a stone's edge, the paper's "passable / non-passable" faces), eroded by ``margin_px`` for
  the foot (the DCM front end's ``steppable_mask``, reused).
* A seed whose s/4 x s/4 neighbourhood holds no usable cell moves to the centroid of the usable
  cells of its whole s x s grid cell (none: no cluster): our holes and risers are wide next to
  s/4, and a stone with no seed on it would be left out.
* Each cluster's centre point is moved along its RANSAC normal onto the plane of the inliers,
  and only the inliers of its largest 4-connected piece make its polygon (SLIC's connectivity
  step; the paper projects every point): a cluster straddling two levels would otherwise get a
  plane between them and a hull across the gap.
* A hull that covers an unusable cell (unknown, unhealthy or unsteppable: e.g. the gap inside a
  U-shaped cluster) is cut, one half-plane per such cell, until it covers none (at most
  ``max_cuts``, else dropped): the MPFC takes every point of a foothold as safe.
* The hull is Andrew's monotone chain, not a Graham scan: the same hull of the same points.
  The regions stage (projection, hull, cuts) runs for all clusters in one numba call
  (``_polygons``) and the footholds are made in one batch (``Foothold.many_from_ccw``): it was
  Python once per cluster, most of a map's time (docs/reports/segmenters.md).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import cv2
import numba
import numpy as np

from processes.dcm_planner.regions import RegionParams, steppable_mask
from processes.superpixels.params import SuperpixelParams
from runtime.geometry import Foothold

STAGES = ("normals", "slic", "regions")

#: a cut passes this far (px) beyond the centre of the cell it clears: half a cell
_CUT_PX = 0.5
#: rounding's reach (px): a hull corner this close to the line of its neighbours is dropped,
#: and a blocked cell's centre this close outside a hull counts as covered. Projecting the
#: cells onto a fitted plane moves them by ~1e-6 px, which would otherwise decide both either
#: way (a grid edge of blocked cells lying along a hull's edge)
_EDGE_PX = 1e-3


def normals(elevation: np.ndarray, resolution: float, window_px: int = 1) -> np.ndarray:
    """Unit upward normals (R, C, 3), NaN where a difference needs an unknown cell.

    Eqs. (5)-(9) on the grid: p_u = (r, 0, dz/du), p_v = (0, r, dz/dv) with the forward
    differences of eq. (7) (backward on the last row and column), n = p_u x p_v (eq. (8); the
    paper's p_v x p_u is the same normal in its y-down camera frame), normalised (eq. (9)). The
    heights are first box-averaged over ``window_px`` known cells (module docstring)."""
    z = np.asarray(elevation, dtype=np.float64)
    if window_px > 1:
        known = np.isfinite(z)
        k = (window_px, window_px)
        num = cv2.blur(np.where(known, z, 0.0), k, borderType=cv2.BORDER_REPLICATE)
        den = cv2.blur(known.astype(np.float64), k, borderType=cv2.BORDER_REPLICATE)
        z = np.where(known, num / np.maximum(den, 1e-12), np.nan)
    dzu = np.empty_like(z)
    dzv = np.empty_like(z)
    if z.shape[1] > 1:
        dzu[:, :-1] = z[:, 1:] - z[:, :-1]  # eq. (7): z(u + 1, v) - z(u, v)
        dzu[:, -1] = dzu[:, -2]
    else:
        dzu[:] = 0.0
    if z.shape[0] > 1:
        dzv[:-1] = z[1:] - z[:-1]  # eq. (7): z(u, v + 1) - z(u, v)
        dzv[-1] = dzv[-2]
    else:
        dzv[:] = 0.0
    n = np.stack((-resolution * dzu, -resolution * dzv,
                  np.full_like(z, resolution * resolution)), axis=-1)  # eq. (8)
    return n / np.linalg.norm(n, axis=-1, keepdims=True)  # eq. (9); NaN stays NaN


def usable_mask(elevation: np.ndarray, normal: np.ndarray, resolution: float,
                p: SuperpixelParams) -> np.ndarray:
    """The cells SLIC may cluster (bool): known, a healthy normal (V-D-1: n . up > the
    threshold; the paper's -e_y of its camera is our up) and steppable (module docstring)."""
    healthy = normal[..., 2] > p.min_normal_z  # NaN compares False: no data
    label = RegionParams(max_slope_deg=89.0, max_step_m=p.max_step_m, margin_px=p.margin_px)
    return healthy & (steppable_mask(elevation, resolution, label) > 0)


@numba.njit(cache=True, nogil=True)
def _assign(usable: np.ndarray, pts: np.ndarray, nrm: np.ndarray, cu: np.ndarray,
            cv: np.ndarray, cp: np.ndarray, cn: np.ndarray, alive: np.ndarray, s: float,
            w: np.ndarray, labels: np.ndarray, dist: np.ndarray) -> None:
    """SLIC's assignment: each usable cell to the cluster of least d_total (eq. (10)) among
    those whose 2s x 2s window holds it. ``w`` is (w_n/d_n^max, w_p/d_p^max, w_w/d_w^max,
    w_c/d_c^max)."""
    rows, cols = usable.shape
    labels[:] = -1
    dist[:] = np.inf
    for k in range(len(cu)):
        if not alive[k]:
            continue
        u0, u1 = max(int(cu[k] - s), 0), min(int(cu[k] + s) + 1, cols)
        v0, v1 = max(int(cv[k] - s), 0), min(int(cv[k] + s) + 1, rows)
        for v in range(v0, v1):
            for u in range(u0, u1):
                if not usable[v, u]:
                    continue
                dx = cp[k, 0] - pts[v, u, 0]
                dy = cp[k, 1] - pts[v, u, 1]
                dz = cp[k, 2] - pts[v, u, 2]
                d_n = 1.0 - (cn[k, 0] * nrm[v, u, 0] + cn[k, 1] * nrm[v, u, 1]
                             + cn[k, 2] * nrm[v, u, 2])  # eq. (11)
                d_p = abs(dx * cn[k, 0] + dy * cn[k, 1] + dz * cn[k, 2])  # eq. (12)
                d_w = math.sqrt(dx * dx + dy * dy + dz * dz)  # eq. (13)
                d_c = math.sqrt((cu[k] - u) ** 2 + (cv[k] - v) ** 2)  # eq. (14)
                d = w[0] * d_n + w[1] * d_p + w[2] * d_w + w[3] * d_c  # eq. (10)
                if d < dist[v, u]:
                    dist[v, u] = d
                    labels[v, u] = k


@numba.njit(cache=True, nogil=True)
def _members(labels: np.ndarray, count: int) -> tuple[np.ndarray, np.ndarray]:
    """Cells grouped by cluster (a counting sort): flat indices and the offsets of each
    cluster's run."""
    flat = labels.ravel()
    start = np.zeros(count + 1, np.int64)
    for i in range(flat.size):
        if flat[i] >= 0:
            start[flat[i] + 1] += 1
    for k in range(count):
        start[k + 1] += start[k]
    fill = start[:-1].copy()
    order = np.empty(start[count], np.int64)
    for i in range(flat.size):
        k = flat[i]
        if k >= 0:
            order[fill[k]] = i
            fill[k] += 1
    return order, start


@numba.njit(cache=True, nogil=True)
def _update(labels: np.ndarray, pts: np.ndarray, cu: np.ndarray, cv: np.ndarray,
            cp: np.ndarray, cn: np.ndarray, alive: np.ndarray, draws: np.ndarray,
            threshold: float) -> None:
    """SLIC's update: each cluster's centre to the centroid of its cells, its normal refined by
    RANSAC (the three-point plane with the most cells within ``threshold``, refitted to them by
    least squares), its centre point moved onto that plane. ``draws`` (K, H, 3) are uniform
    samples in [0, 1): the seeded RNG's, so the same map gives the same planes."""
    rows, cols = labels.shape
    order, start = _members(labels, len(cu))
    flat_pts = pts.reshape(rows * cols, 3)
    for k in range(len(cu)):
        m = start[k + 1] - start[k]
        if m < 3:
            alive[k] = False
            continue
        idx = order[start[k]:start[k + 1]]
        q = flat_pts[idx]
        cu[k] = np.mean(idx % cols)
        cv[k] = np.mean(idx // cols)
        centre = np.array([np.mean(q[:, 0]), np.mean(q[:, 1]), np.mean(q[:, 2])])
        best = -1
        best_n = cn[k].copy()
        best_p = centre
        for h in range(draws.shape[1]):
            a = q[int(draws[k, h, 0] * m)]
            b = q[int(draws[k, h, 1] * m)]
            c = q[int(draws[k, h, 2] * m)]
            e1x, e1y, e1z = b[0] - a[0], b[1] - a[1], b[2] - a[2]
            e2x, e2y, e2z = c[0] - a[0], c[1] - a[1], c[2] - a[2]
            nx, ny, nz = e1y * e2z - e1z * e2y, e1z * e2x - e1x * e2z, e1x * e2y - e1y * e2x
            norm = math.sqrt(nx * nx + ny * ny + nz * nz)
            if norm < 1e-12:
                continue
            nx, ny, nz = nx / norm, ny / norm, nz / norm
            off = a[0] * nx + a[1] * ny + a[2] * nz
            inliers = 0
            for j in range(m):
                if abs(q[j, 0] * nx + q[j, 1] * ny + q[j, 2] * nz - off) < threshold:
                    inliers += 1
            if inliers > best:
                best = inliers
                best_n = np.array([nx, ny, nz])
                best_p = a.copy()
        if best >= 3:  # refit to the inliers by least squares, z = a x + b y + c
            sx = sy = sz = sxx = syy = sxy = sxz = syz = 0.0
            cnt = 0
            for j in range(m):
                if abs((q[j, 0] - best_p[0]) * best_n[0] + (q[j, 1] - best_p[1]) * best_n[1]
                       + (q[j, 2] - best_p[2]) * best_n[2]) < threshold:
                    x, y, z = q[j, 0], q[j, 1], q[j, 2]
                    cnt += 1
                    sx += x
                    sy += y
                    sz += z
                    sxx += x * x
                    syy += y * y
                    sxy += x * y
                    sxz += x * z
                    syz += y * z
            mx, my, mz = sx / cnt, sy / cnt, sz / cnt
            cxx, cyy, cxy = sxx - cnt * mx * mx, syy - cnt * my * my, sxy - cnt * mx * my
            cxz, cyz = sxz - cnt * mx * mz, syz - cnt * my * mz
            det = cxx * cyy - cxy * cxy
            if det > 1e-18:  # else (the inliers on a line) the three-point plane stays
                ga = (cyy * cxz - cxy * cyz) / det
                gb = (cxx * cyz - cxy * cxz) / det
                norm = math.sqrt(1.0 + ga * ga + gb * gb)
                best_n = np.array([-ga / norm, -gb / norm, 1.0 / norm])
            if best_n[2] < 0.0:
                best_n = -best_n
            cn[k] = best_n
            # the centre point onto the inliers' plane, along its normal
            cp[k] = centre + ((mx - centre[0]) * best_n[0] + (my - centre[1]) * best_n[1]
                              + (mz - centre[2]) * best_n[2]) * best_n
        else:
            cp[k] = centre


@numba.njit(cache=True, nogil=True)
def _largest_pieces(labels: np.ndarray, count: int) -> np.ndarray:
    """The labels with each cluster cut to its largest 4-connected piece (the rest -1)."""
    rows, cols = labels.shape
    piece = np.full((rows, cols), -1, np.int64)
    sizes = np.zeros(rows * cols, np.int64)
    best = np.full(count, -1, np.int64)
    stack = np.empty(rows * cols, np.int64)
    pieces = 0
    for start in range(rows * cols):
        r0, c0 = start // cols, start % cols
        lab = labels[r0, c0]
        if lab < 0 or piece[r0, c0] >= 0:
            continue
        piece[r0, c0] = pieces
        top = 0
        stack[0] = start
        size = 0
        while top >= 0:
            i = stack[top]
            top -= 1
            size += 1
            r, c = i // cols, i % cols
            for dr, dc in ((1, 0), (-1, 0), (0, 1), (0, -1)):
                rr, cc = r + dr, c + dc
                if 0 <= rr < rows and 0 <= cc < cols and piece[rr, cc] < 0 \
                        and labels[rr, cc] == lab:
                    piece[rr, cc] = pieces
                    top += 1
                    stack[top] = rr * cols + cc
        sizes[pieces] = size
        if best[lab] < 0 or size > sizes[best[lab]]:
            best[lab] = pieces
        pieces += 1
    out = labels.copy()
    for r in range(rows):
        for c in range(cols):
            if out[r, c] >= 0 and piece[r, c] != best[out[r, c]]:
                out[r, c] = -1
    return out


@numba.njit(cache=True, nogil=True)
def _seeds(usable: np.ndarray, pts: np.ndarray, nrm: np.ndarray, s: float
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Initial clusters (V-D-3): one per grid step s, moved to the centroid of the usable cells
    of its s/4 x s/4 neighbourhood (else of its s x s grid cell; none: no cluster). Returns
    pixel centres u, v, points and unit normals."""
    rows, cols = usable.shape
    nv, nu = max(int(rows / s + 0.5), 1), max(int(cols / s + 0.5), 1)
    cu = np.empty(nv * nu)
    cv = np.empty(nv * nu)
    cp = np.empty((nv * nu, 3))
    cn = np.empty((nv * nu, 3))
    count = 0
    for i in range(nv):
        for j in range(nu):
            v0 = min(int(s / 2.0 + i * s), rows - 1)  # the seed on the grid
            u0 = min(int(s / 2.0 + j * s), cols - 1)
            # the odd window at or below s/4 first, then the grid cell's s x s
            for half in (max(int(s / 8.0), 1), int(s / 2.0 + 0.5)):
                m = 0.0
                su = sv = 0.0
                sp = np.zeros(3)
                sn = np.zeros(3)
                for v in range(max(v0 - half, 0), min(v0 + half + 1, rows)):
                    for u in range(max(u0 - half, 0), min(u0 + half + 1, cols)):
                        if usable[v, u]:
                            m += 1.0
                            su += u
                            sv += v
                            sp += pts[v, u]
                            sn += nrm[v, u]
                if m > 0.0:
                    cu[count], cv[count] = su / m, sv / m
                    cp[count] = sp / m
                    cn[count] = sn / math.sqrt(sn[0] ** 2 + sn[1] ** 2 + sn[2] ** 2)
                    count += 1
                    break
    return cu[:count], cv[:count], cp[:count], cn[:count]


@dataclass
class SuperpixelResult:
    """One map's output: the usable cells (the "safe" mask), the final superpixel labels
    (-1: none), the footholds (world frame) and per-stage times (ms)."""

    status: str
    safe_mask: np.ndarray
    labels: np.ndarray
    footholds: list[Foothold]
    times_ms: dict[str, float] = field(default_factory=dict)


class SuperpixelSegmenter:
    """QuadPiPS' superpixel planar regions, one map at a time: no memory between maps."""

    def __init__(self, params: SuperpixelParams | None = None) -> None:
        self.params = params if params is not None else SuperpixelParams()
        p = self.params
        self._weights = np.array([p.w_n / p.d_n_max, p.w_p / p.d_p_max_m, p.w_w / p.d_w_max_m,
                                  p.w_c / p.d_c_max_px])
        # compile (or load from numba's cache) now, not on the first map
        warm = np.zeros((12, 12))
        warm[:, 6:] = 0.2
        self.segment(warm, 0.025, np.zeros(2))

    def process(self, elevation: np.ndarray, resolution: float, origin_xy: np.ndarray,
                map_time_s: float | None = None) -> list[Foothold]:
        """The map's footholds: what the S3 process publishes in S3's place (as
        ``ContourRegions.process``; no state, so the map's time is not used)."""
        return self.segment(elevation, resolution, origin_xy).footholds

    def segment(self, elevation: np.ndarray, resolution: float,
                origin_xy: np.ndarray) -> SuperpixelResult:
        """Segment one elevation map (rows along y, NaN unknown; origin = centre of cell
        (0, 0)) into convex planar footholds."""
        p = self.params
        t0 = time.perf_counter()
        e = np.asarray(elevation, dtype=np.float64)
        if e.ndim != 2 or e.size == 0 or not np.isfinite(e).any():
            empty = np.zeros(e.shape if e.ndim == 2 else (0, 0), np.uint8)
            return SuperpixelResult("no data", empty, empty.astype(np.int64), [],
                                    {s: 0.0 for s in STAGES} | {"total": 0.0})
        rows, cols = e.shape
        nrm = normals(e, resolution, p.normal_window_px)
        usable = usable_mask(e, nrm, resolution, p)
        t1 = time.perf_counter()
        # the cells' points in metres from cell (0, 0) (world = these + origin)
        jj, ii = np.meshgrid(np.arange(cols) * resolution, np.arange(rows) * resolution)
        pts = np.ascontiguousarray(np.stack((jj, ii, np.where(usable, e, 0.0)), axis=-1))
        nrm = np.ascontiguousarray(np.where(usable[..., None], nrm, 0.0))
        s = math.sqrt(rows * cols / p.k_des)  # s_low = sqrt(n_low / k_des)
        labels = np.full((rows, cols), -1, np.int64)
        if usable.any():
            cu, cv, cp, cn = _seeds(usable, pts, nrm, s)
            alive = np.ones(len(cu), np.bool_)
            dist = np.empty((rows, cols))
            rng = np.random.default_rng(p.seed)
            for _ in range(p.n_iter):
                _assign(usable, pts, nrm, cu, cv, cp, cn, alive, s, self._weights, labels,
                        dist)
                draws = rng.random((len(cu), p.ransac_hypotheses, 3))
                _update(labels, pts, cu, cv, cp, cn, alive, draws, p.ransac_threshold_m)
            labels = _largest_pieces(labels, len(cu))
            # only the cells on their cluster's plane make its polygon
            off = np.abs(np.einsum("ijk,ijk->ij", pts - cp[labels], cn[labels]))
            labels[(labels >= 0) & (off >= p.ransac_threshold_m)] = -1
            t2 = time.perf_counter()
            footholds = self._regions(labels, pts, usable, cu, cv, cp, cn, resolution,
                                      np.asarray(origin_xy, dtype=np.float64))
        else:
            t2 = time.perf_counter()
            footholds = []
        t3 = time.perf_counter()
        times = {"normals": (t1 - t0) * 1e3, "slic": (t2 - t1) * 1e3,
                 "regions": (t3 - t2) * 1e3, "total": (t3 - t0) * 1e3}
        status = "ok" if footholds else "no safe terrain"
        return SuperpixelResult(status, usable.astype(np.uint8), labels, footholds, times)

    def _regions(self, labels: np.ndarray, pts: np.ndarray, usable: np.ndarray,
                 cu: np.ndarray, cv: np.ndarray, cp: np.ndarray, cn: np.ndarray,
                 resolution: float, origin: np.ndarray) -> list[Foothold]:
        """V-E: each cluster's cells projected onto its plane (p_zeta, n_zeta), their convex
        hull, cut clear of unusable cells, lifted onto the plane as a foothold: the geometry of
        all clusters in one numba call (``_polygons``), the footholds in one batch."""
        p = self.params
        order, start = _members(labels, len(cu))
        n = cn / np.linalg.norm(cn, axis=1, keepdims=True)
        min_px = max(p.min_area_m2 / (resolution * resolution), 1e-9)
        verts, bounds, which = _polygons(pts.reshape(-1, 3), order, start, labels.shape[1],
                                         resolution, cu, cv, cp, n, ~usable, p.max_cuts,
                                         min_px)
        lift = n[which] @ np.append(origin, 0.0) + np.einsum("ij,ij->i", n[which], cp[which])
        return Foothold.many_from_ccw(origin + verts * resolution, bounds, n[which], lift)


@numba.njit(cache=True, nogil=True)
def _cross(o: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    """z of (a - o) x (b - o): > 0 when o -> a -> b turns left (counter-clockwise)."""
    return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])


@numba.njit(cache=True, nogil=True)
def _hull(xy: np.ndarray, out: np.ndarray) -> int:
    """Convex hull of 2D points by Andrew's monotone chain, counter-clockwise from the least
    (x, y), written to ``out`` (room for 2 len(xy) + 1); returns the corner count. The chain
    drops only points strictly inside or on a line (no tolerance: with one, points a rounding
    error apart in x, sorted out of line, can lose a true corner); corners within _EDGE_PX of
    the line of their neighbours go afterwards (the grid's rows of cells), which only shrinks
    the hull by as much."""
    m = len(xy)
    by_y = np.argsort(xy[:, 1], kind="mergesort")
    idx = by_y[np.argsort(xy[by_y, 0], kind="mergesort")]  # by x, then y
    h = 0
    for j in range(m):  # the lower chain, left to right
        q = xy[idx[j]]
        while h >= 2 and _cross(out[h - 2], out[h - 1], q) <= 0.0:
            h -= 1
        out[h] = q
        h += 1
    low = h + 1
    for j in range(m - 2, -1, -1):  # the upper chain, right to left
        q = xy[idx[j]]
        while h >= low and _cross(out[h - 2], out[h - 1], q) <= 0.0:
            h -= 1
        out[h] = q
        h += 1
    h -= 1  # the last is the first again
    dropped = True
    while dropped and h >= 3:  # the corners (almost) on the line of their neighbours
        dropped = False
        for i in range(h):
            a, b = out[i - 1 if i > 0 else h - 1], out[i + 1 if i + 1 < h else 0]
            if _cross(a, out[i], b) <= _EDGE_PX * math.hypot(b[0] - a[0], b[1] - a[1]):
                out[i:h - 1] = out[i + 1:h].copy()
                h -= 1
                dropped = True
                break
    return h


@numba.njit(cache=True, nogil=True)
def _depth(poly: np.ndarray, k: int, x: float, y: float) -> float:
    """Signed distance of (x, y) to the boundary of the CCW convex polygon poly[:k] (px,
    positive inside): the least over its edges' inward lines."""
    depth = np.inf
    for i in range(k):
        j = i + 1 if i + 1 < k else 0
        nx, ny = poly[i, 1] - poly[j, 1], poly[j, 0] - poly[i, 0]  # inward: the edge turned left
        norm = max(math.sqrt(nx * nx + ny * ny), 1e-300)
        nx, ny = nx / norm, ny / norm
        depth = min(depth, x * nx + y * ny - (nx * poly[i, 0] + ny * poly[i, 1]))
    return depth


@numba.njit(cache=True, nogil=True)
def _clip(poly: np.ndarray, k: int, ax: float, ay: float, c: float, out: np.ndarray) -> int:
    """poly[:k] (convex) cut to {x : a . x >= c} (one Sutherland-Hodgman pass) into ``out``,
    corners closer than 1e-9 px to the next merged; returns the corner count."""
    h = 0
    for i in range(k):
        j = i + 1 if i + 1 < k else 0
        si = poly[i, 0] * ax + poly[i, 1] * ay - c
        sj = poly[j, 0] * ax + poly[j, 1] * ay - c
        if si >= -1e-12:
            out[h] = poly[i]
            h += 1
        if (si >= -1e-12) != (sj >= -1e-12):
            t = si / (si - sj)
            out[h, 0] = poly[i, 0] + t * (poly[j, 0] - poly[i, 0])
            out[h, 1] = poly[i, 1] + t * (poly[j, 1] - poly[i, 1])
            h += 1
    kept = 0
    for i in range(h):
        j = i + 1 if i + 1 < h else 0
        if math.hypot(out[i, 0] - out[j, 0], out[i, 1] - out[j, 1]) > 1e-9:
            out[kept] = out[i]
            kept += 1
    return kept if kept > 0 or h == 0 else 1


@numba.njit(cache=True, nogil=True)
def _polygons(pts: np.ndarray, order: np.ndarray, start: np.ndarray, cols: int, r: float,
              cu: np.ndarray, cv: np.ndarray, cp: np.ndarray, n: np.ndarray,
              blocked: np.ndarray, max_cuts: int, min_px: float
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """V-E for every cluster of three cells or more and an upward normal: its cells
    (``order[start[k]:start[k + 1]]``, flat indices of ``pts``, metres from cell (0, 0))
    projected onto its plane (cp[k], n[k]) in px of r metres (x = col, y = row), their convex
    hull, cut until no blocked cell's centre lies in it or within _EDGE_PX of it: each cut the
    half-plane facing the cluster's cell nearest (cu, cv) half a cell beyond the covered
    blocked cell nearest to that cell, so each cut clears at least that cell and keeps the
    anchor (dropped after ``max_cuts``, or with less than ``min_px`` px^2 left). Returns the
    polygons' corners back to back (CCW, px), their K + 1 bounds and the cluster of each."""
    rows = blocked.shape[0]
    count = len(cu)
    verts = np.empty((len(order) + count * (max_cuts + 1), 2))
    bounds = np.zeros(count + 1, np.int64)
    which = np.empty(count, np.int64)
    done = 0
    for k in range(count):
        a, b = start[k], start[k + 1]
        m = b - a
        if m < 3 or n[k, 2] <= 0.0:
            continue
        xy = np.empty((m, 2))  # the cells onto the plane along its normal, in px
        best = np.inf
        anchor_x = anchor_y = 0.0
        for j in range(m):
            i = order[a + j]
            along = ((pts[i, 0] - cp[k, 0]) * n[k, 0] + (pts[i, 1] - cp[k, 1]) * n[k, 1]
                     + (pts[i, 2] - cp[k, 2]) * n[k, 2])
            xy[j, 0] = (pts[i, 0] - along * n[k, 0]) / r
            xy[j, 1] = (pts[i, 1] - along * n[k, 1]) / r
            d2 = (i % cols - cu[k]) ** 2 + (i // cols - cv[k]) ** 2
            if d2 < best:  # the anchor: the cluster's cell nearest its centre (the first)
                best = d2
                anchor_x, anchor_y = float(i % cols), float(i // cols)
        poly = np.empty((2 * m + max_cuts + 2, 2))  # the hull's two chains, then the cuts
        spare = np.empty_like(poly)
        h = _hull(xy, poly)
        if h < 3:  # the cells on one line
            continue
        # the blocked cells in the hull's bounding box
        x0 = max(math.floor(poly[:h, 0].min()), 0)
        y0 = max(math.floor(poly[:h, 1].min()), 0)
        x1 = min(math.ceil(poly[:h, 0].max()) + 1, cols)
        y1 = min(math.ceil(poly[:h, 1].max()) + 1, rows)
        bad = np.empty((max(x1 - x0, 0) * max(y1 - y0, 0), 2))
        nb = 0
        for y in range(y0, y1):
            for x in range(x0, x1):
                if blocked[y, x]:
                    bad[nb, 0], bad[nb, 1] = x, y
                    nb += 1
        clear = False
        for _ in range(max_cuts + 1):
            if h < 3:
                break
            kept = 0  # the blocked cells still inside (or on an edge)
            for j in range(nb):
                if _depth(poly, h, bad[j, 0], bad[j, 1]) >= -_EDGE_PX:
                    bad[kept] = bad[j]
                    kept += 1
            nb = kept
            if nb == 0:
                clear = True
                break
            near, dist = 0, np.inf
            for j in range(nb):
                dj = math.hypot(bad[j, 0] - anchor_x, bad[j, 1] - anchor_y)
                if dj < dist:
                    near, dist = j, dj
            ux, uy = anchor_x - bad[near, 0], anchor_y - bad[near, 1]
            norm = math.hypot(ux, uy)
            ux, uy = ux / norm, uy / norm
            h = _clip(poly, h, ux, uy, ux * bad[near, 0] + uy * bad[near, 1] + _CUT_PX, spare)
            poly, spare = spare, poly
        if not clear or h < 3:
            continue
        area = 0.0  # the shoelace sum
        for i in range(h):
            j = i - 1 if i > 0 else h - 1
            area += poly[j, 0] * poly[i, 1] - poly[i, 0] * poly[j, 1]
        if 0.5 * area < min_px:
            continue
        o = bounds[done]
        verts[o:o + h] = poly[:h]
        bounds[done + 1] = o + h
        which[done] = k
        done += 1
    return verts[:bounds[done]], bounds[:done + 1], which[:done]
