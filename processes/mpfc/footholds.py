"""Convex polygon footholds (Section IV-C) and the 2D geometry the exact search needs.

A foothold is {p in R^3 : A p <= b, normal . p = offset}, the paper's F_i p <= c_i and
f_i^T p = b_i of (20). Rows of A and the normal are normalised to unit length on construction,
so that the big-M of (20) relaxes every row by M metres, as the paper requires.

Because neither the ALIP dynamics nor the costs depend on footstep height (R has a zero z
weight), the search works on the horizontal projection of each foothold: z is eliminated with
the plane equation, leaving 2D halfspaces F p_xy <= c and the polygon's 2D vertices.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np


@dataclass(frozen=True, eq=False)
class Foothold:
    """Convex polygon {p : A p <= b, normal . p = offset} in the world frame (metres)."""

    A: np.ndarray
    b: np.ndarray
    normal: np.ndarray
    offset: float

    def __post_init__(self) -> None:
        a = np.array(self.A, dtype=float).reshape(-1, 3)
        b = np.array(self.b, dtype=float).reshape(-1)
        n = np.array(self.normal, dtype=float).reshape(3)
        if a.shape[0] != b.shape[0] or a.shape[0] < 3:
            raise ValueError("Foothold needs k >= 3 halfspace rows with matching A and b")
        nn = float(np.linalg.norm(n))
        if not np.isfinite(nn) or nn == 0.0:
            raise ValueError("Foothold normal must be a non-zero finite vector")
        off = float(self.offset) / nn
        n = n / nn
        if n[2] < 0:  # orient the normal upward so the plane z-solve below is uniform
            n, off = -n, -off
        rn = np.linalg.norm(a, axis=1)
        if np.any(rn == 0.0) or not np.all(np.isfinite(a)) or not np.all(np.isfinite(b)):
            raise ValueError("Foothold rows must be finite and non-zero")
        a = a / rn[:, None]
        b = b / rn
        for arr in (a, b, n):
            arr.setflags(write=False)
        object.__setattr__(self, "A", a)
        object.__setattr__(self, "b", b)
        object.__setattr__(self, "normal", n)
        object.__setattr__(self, "offset", off)

    @classmethod
    def from_polygon(
        cls,
        vertices_xy: np.ndarray,
        normal: np.ndarray | tuple[float, float, float] = (0.0, 0.0, 1.0),
        offset: float = 0.0,
    ) -> Foothold:
        """Foothold from a convex 2D polygon (any orientation) lifted onto the plane n . p = d.

        The halfspaces are vertical walls through the polygon's edges (A[:, 2] = 0).
        """
        v = _convex_ccw(np.asarray(vertices_xy, dtype=float).reshape(-1, 2))
        edges = np.roll(v, -1, axis=0) - v
        out = np.column_stack([edges[:, 1], -edges[:, 0], np.zeros(len(v))])  # outward normals
        b = np.einsum("ij,ij->i", out[:, :2], v)
        fh = cls(out, b, np.asarray(normal, dtype=float), float(offset))
        # vertical walls: the horizontal projection is the polygon itself (fill the caches)
        v.setflags(write=False)
        fh.__dict__["vertices_xy"] = v
        fh.__dict__["halfspaces_xy"] = (fh.A[:, :2], fh.b)
        return fh

    @classmethod
    def from_vertices_3d(cls, vertices: np.ndarray) -> Foothold:
        """Foothold from 3D vertices of a planar convex polygon (plane by least squares)."""
        v = np.asarray(vertices, dtype=float).reshape(-1, 3)
        centre = v.mean(axis=0)
        _, _, vt = np.linalg.svd(v - centre)
        n = vt[2] if vt[2, 2] >= 0 else -vt[2]
        return cls.from_polygon(v[:, :2], n, float(n @ centre))

    @cached_property
    def plane_xy(self) -> tuple[np.ndarray, float]:
        """(beta, alpha) with z = alpha + beta . p_xy on the foothold plane."""
        n = self.normal
        return -n[:2] / n[2], self.offset / n[2]

    @cached_property
    def halfspaces_xy(self) -> tuple[np.ndarray, np.ndarray]:
        """2D halfspaces (F, c) of the horizontal projection, z eliminated by the plane."""
        beta, alpha = self.plane_xy
        f = self.A[:, :2] + np.outer(self.A[:, 2], beta)
        c = self.b - self.A[:, 2] * alpha
        nrm = np.linalg.norm(f, axis=1)
        keep = nrm > 1e-12
        return f[keep] / nrm[keep, None], c[keep] / nrm[keep]

    @cached_property
    def vertices_xy(self) -> np.ndarray:
        """Counter-clockwise 2D vertices of the projection (empty (0, 2) if it is empty)."""
        f, c = self.halfspaces_xy
        return _vertices_from_halfspaces(f, c)

    def contains(self, p: np.ndarray, tol: float = 1e-6) -> bool:
        """True when the 3D point p lies in the foothold (to `tol` metres)."""
        p = np.asarray(p, dtype=float)
        on_plane = abs(self.normal @ p - self.offset) <= tol
        return bool(np.all(self.A @ p <= self.b + tol) and on_plane)

    def height_at(self, p_xy: np.ndarray) -> float:
        """z of the foothold plane above the horizontal point p_xy."""
        beta, alpha = self.plane_xy
        return float(alpha + beta @ np.asarray(p_xy, dtype=float)[:2])


def _convex_ccw(v: np.ndarray) -> np.ndarray:
    """Order the vertices of a convex polygon counter-clockwise and drop duplicates."""
    centre = v.mean(axis=0)
    ang = np.arctan2(v[:, 1] - centre[1], v[:, 0] - centre[0])
    v = v[np.argsort(ang)]
    keep = np.linalg.norm(v - np.roll(v, 1, axis=0), axis=1) > 1e-12
    v = v[keep]
    if len(v) < 3:
        raise ValueError("a foothold polygon needs at least 3 distinct vertices")
    return v


def _vertices_from_halfspaces(f: np.ndarray, c: np.ndarray, tol: float = 1e-9) -> np.ndarray:
    """Vertices of {p : F p <= c} in 2D from all pairwise line intersections (k is small)."""
    k = len(f)
    i, j = np.triu_indices(k, 1)
    det = f[i, 0] * f[j, 1] - f[i, 1] * f[j, 0]
    ok = np.abs(det) > 1e-12
    i, j, det = i[ok], j[ok], det[ok]
    x = (c[i] * f[j, 1] - c[j] * f[i, 1]) / det
    y = (f[i, 0] * c[j] - f[j, 0] * c[i]) / det
    pts = np.column_stack([x, y])
    if len(pts) == 0:
        return np.zeros((0, 2))
    inside = np.all(pts @ f.T <= c + tol * (1.0 + np.abs(c)), axis=1)
    pts = pts[inside]
    if len(pts) < 3:
        return np.zeros((0, 2))
    pts = np.unique(np.round(pts, 12), axis=0)
    centre = pts.mean(axis=0)
    return pts[np.argsort(np.arctan2(pts[:, 1] - centre[1], pts[:, 0] - centre[0]))]


@dataclass
class LocalFootholds:
    """Pruned footholds expressed in the stance (yaw) frame, padded for vectorised use.

    F (M, K, 2), c (M, K): 2D halfspaces (padding rows are 0 <= +inf);
    V (M, Kv, 2): CCW vertices (padding repeats the last vertex); Ed (M, Kv, 2): edge vectors;
    beta (M, 2), alpha (M,): local plane z = alpha + beta . p_xy;
    index (M,): positions in the caller's foothold list; box_lo/box_hi: box around them all.
    `three_d()` gives the 3D halfspaces and planes for the big-M form (20).
    """

    F: np.ndarray
    c: np.ndarray
    V: np.ndarray
    Ed: np.ndarray
    beta: np.ndarray
    alpha: np.ndarray
    index: np.ndarray
    box_lo: np.ndarray
    box_hi: np.ndarray
    world: WorldFootholds | None = None
    order: np.ndarray | None = None
    p_stance: np.ndarray | None = None
    rot: np.ndarray | None = None

    @property
    def count(self) -> int:
        """Number of footholds kept."""
        return int(self.index.shape[0])

    def three_d(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(A3 (M, K3, 3), b3 (M, K3), n3 (M, 3), d3 (M,)) in the stance frame; padding rows of
        A3 are zero with b3 = +inf."""
        w, o, ps, rot = self.world, self.order, self.p_stance, self.rot
        assert w is not None and o is not None and ps is not None and rot is not None
        a3 = w.A3[o] @ rot
        b3 = w.b3[o] - np.einsum("mkj,j->mk", w.A3[o], ps)
        n3 = w.n3[o] @ rot
        d3 = w.d3[o] - w.n3[o] @ ps
        return a3, b3, n3, d3


def yaw_rotation(yaw: float) -> np.ndarray:
    """3x3 rotation about world z by `yaw` (stance frame axes expressed in world)."""
    cy, sy = np.cos(yaw), np.sin(yaw)
    return np.array([[cy, -sy, 0.0], [sy, cy, 0.0], [0.0, 0.0, 1.0]])


class WorldFootholds:
    """A foothold list padded into arrays once (footholds change at 30 Hz, solves run faster).

    Per solve, `local` prunes and transforms these arrays to the stance frame without a
    per-foothold Python loop.
    """

    def __init__(self, footholds: list[Foothold], min_normal_z: float) -> None:
        self.source = list(footholds)
        ok = [
            i for i, fh in enumerate(self.source)
            if fh.normal[2] >= min_normal_z and len(fh.vertices_xy) >= 3
        ]
        fhs = [self.source[i] for i in ok]
        m = len(ok)
        kc = np.array([len(f.halfspaces_xy[1]) for f in fhs], dtype=int)
        kv = np.array([len(f.vertices_xy) for f in fhs], dtype=int)
        k3 = np.array([len(f.b) for f in fhs], dtype=int)
        self.index = np.array(ok, dtype=int)
        self.F = np.zeros((m, max(kc.max(initial=0), 4), 2))
        self.c = np.full((m, self.F.shape[1]), np.inf)
        self.V = np.zeros((m, max(kv.max(initial=0), 3), 2))
        self.Ed = np.zeros_like(self.V)
        self.A3 = np.zeros((m, max(k3.max(initial=0), 4), 3))
        self.b3 = np.full((m, self.A3.shape[1]), np.inf)
        if m == 0:
            self.n3 = np.zeros((0, 3))
            self.d3 = self.alpha = np.zeros(0)
            self.beta = np.zeros((0, 2))
            return
        # scatter the concatenated per-foothold arrays into the padded ones in one go each
        rows, slots = _ragged_index(kc)
        self.F[rows, slots] = np.concatenate([f.halfspaces_xy[0] for f in fhs])
        self.c[rows, slots] = np.concatenate([f.halfspaces_xy[1] for f in fhs])
        rows, slots = _ragged_index(k3)
        self.A3[rows, slots] = np.concatenate([f.A for f in fhs])
        self.b3[rows, slots] = np.concatenate([f.b for f in fhs])
        vcat = np.concatenate([f.vertices_xy for f in fhs])
        rows, slots = _ragged_index(kv)
        starts = np.cumsum(kv) - kv
        self.V[:] = vcat[starts + kv - 1][:, None, :]  # padding repeats the last vertex
        self.V[rows, slots] = vcat
        # edge i runs to vertex i+1, the last one back to the first; padding edges are zero
        nxt = starts[rows] + (slots + 1) % kv[rows]
        self.Ed[rows, slots] = vcat[nxt] - vcat
        self.n3 = np.array([f.normal for f in fhs])
        self.d3 = np.array([f.offset for f in fhs])
        self.beta = -self.n3[:, :2] / self.n3[:, 2:3]
        self.alpha = self.d3 / self.n3[:, 2]

    def local(
        self, p_stance: np.ndarray, yaw: float, max_count: int, max_distance: float,
        anchor: float = 0.0,
    ) -> LocalFootholds:
        """Prune by horizontal distance to the stance foot (nearest first, at most `max_count`
        within `max_distance`), then express the kept footholds in the stance frame.

        With ``anchor`` > 0 and a foothold within that distance of the stance foot, heights
        are taken relative to that foothold's plane under the foot rather than to the foot's
        own z: the foot stands on it, so this cancels a vertical offset between the footholds'
        frame and the state estimate's (drift; ground-truth footholds in an estimated frame)."""
        p_stance = np.asarray(p_stance, dtype=float)
        s2 = p_stance[:2]
        m_all = self.index.shape[0]
        if m_all:
            inside = np.all(self.F @ s2 <= self.c + 1e-12, axis=1)
            d2 = edge_dist_sq(s2[None, None, :], self.V, self.Ed)
            d2[inside] = 0.0
            order = np.argsort(d2, kind="stable")
            order = order[d2[order] <= max_distance**2][:max_count]
        else:
            order = np.zeros(0, dtype=int)
        rot = yaw_rotation(yaw)
        r2 = rot[:2, :2]
        fo = self.F[order]
        f = fo @ r2  # F_w (s + R2 p) <= c  ->  (F_w R2) p <= c - F_w s
        c = self.c[order] - fo @ s2
        v = (self.V[order] - s2) @ r2
        ed = self.Ed[order] @ r2
        # plane z_w = alpha + beta . (s + R2 p)  ->  z_local = z_w - s_z
        beta = self.beta[order] @ r2
        z_ref = p_stance[2]
        if anchor > 0.0 and len(order) and d2[order[0]] <= anchor * anchor:
            k = order[0]  # the nearest foothold: the one the stance foot stands on
            z_ref = float(self.alpha[k] + self.beta[k] @ s2)
        alpha = self.alpha[order] + self.beta[order] @ s2 - z_ref
        if len(order):
            flat = v.reshape(-1, 2)
            box_lo = flat.min(axis=0)
            box_hi = flat.max(axis=0)
        else:
            box_lo = np.zeros(2)
            box_hi = np.zeros(2)
        return LocalFootholds(f, c, v, ed, beta, alpha, self.index[order], box_lo, box_hi,
                              self, order, p_stance, rot)


def _ragged_index(counts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(row, slot) of every element of rows with `counts` elements, flattened in order."""
    rows = np.repeat(np.arange(len(counts)), counts)
    starts = np.cumsum(counts) - counts
    return rows, np.arange(int(counts.sum())) - starts[rows]


def edge_dist_sq(points: np.ndarray, verts: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """Squared distance from points to polygon boundaries, broadcast over leading axes.

    points (..., 1, 2), verts/edges (..., K, 2) -> (...,): min over edges of the point-segment
    distance (zero-length padding edges reduce to the vertex distance).
    """
    wx = points[..., 0] - verts[..., 0]
    wy = points[..., 1] - verts[..., 1]
    ex, ey = edges[..., 0], edges[..., 1]
    ee = ex * ex + ey * ey
    ee[ee == 0.0] = 1.0
    t = (wx * ex + wy * ey) / ee
    np.clip(t, 0.0, 1.0, out=t)
    wx -= t * ex
    wy -= t * ey
    return (wx * wx + wy * wy).min(axis=-1)
