"""The one foothold type: a convex polygon on a plane, for S3, the MPFC, the sim and the tools.

A foothold is the set {p in R^3 : A p <= b, normal . p = offset} in the world frame (metres):
the paper's convex polygon P_i with its plane f_i^T p = b_i and its half-spaces F_i p <= c_i
(Section IV-C). The half-space form is what the MPFC's foothold constraint (15d) needs: its
big-M form (20a)-(20c) relaxes each row by M(1 - mu_{n,i}), which is M metres only when the
rows and the normal have unit length ("appropriately normalized F_i and f_i"), so every
constructor here gives unit rows and a unit, upward normal. The vertices are the other half:
S3's convex decomposition and plane fit (Section VI-B, Fig. 7) produce polygons by their
corners, which the foothold set carries for display and the judge of an experiment uses.

Because neither the ALIP dynamics nor the MPFC's costs depend on footstep height, the search
works on the horizontal projection: ``halfspaces_xy`` eliminates z with the plane equation,
leaving F p_xy <= c, and ``vertices_xy`` is that polygon's corners.

Three ways in, all exact about rounding so that what a source computed is what goes out:

* ``Foothold(A, b, normal, offset)``: the half-space form, rows and normal scaled to unit
  length here (what a received foothold set becomes: ``runtime.codecs``);
* ``Foothold.from_polygon(vertices_xy, normal, offset)``: corners in any order, sorted
  counter-clockwise, walls through the edges (hand-made and random footholds);
* ``Foothold.from_ccw(vertices_xy, normal, offset)``: corners already counter-clockwise, kept
  in their order with the plane exactly as given (S3's polygons, the sim's box tops);
  ``Foothold.many_from_ccw`` does the same for many polygons at once (the superpixels'
  dozens a map).

(``Foothold.from_vertices`` takes 3D corners, fits their plane and goes through
``from_polygon``.) A polygon with fewer than three distinct corners or no area is refused with
a ValueError that says so.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property

import numpy as np

Vector = np.ndarray | Sequence[float]


@dataclass(frozen=True, eq=False)
class Foothold:
    """Convex polygon {p : A p <= b, normal . p = offset} in the world frame (metres)."""

    A: np.ndarray
    b: np.ndarray
    normal: np.ndarray
    offset: float

    def __post_init__(self) -> None:
        """Check the half-spaces and scale rows and normal to unit length, normal upward."""
        a = np.array(self.A, dtype=float).reshape(-1, 3)
        b = np.array(self.b, dtype=float).reshape(-1)
        n = np.array(self.normal, dtype=float).reshape(3)
        if a.shape[0] != b.shape[0] or a.shape[0] < 3:
            raise ValueError(f"a foothold needs k >= 3 half-space rows with as many offsets, "
                             f"got {a.shape[0]} rows and {b.shape[0]} offsets")
        nn = float(np.linalg.norm(n))
        if not np.isfinite(nn) or nn == 0.0:
            raise ValueError(f"a foothold's normal must be a non-zero finite vector, got {n}")
        if not np.isfinite(self.offset):
            raise ValueError(f"a foothold's plane offset must be finite, got {self.offset}")
        off = float(self.offset) / nn
        n = n / nn
        if n[2] < 0:  # orient the normal upward so the plane z-solve below is uniform
            n, off = -n, -off
        rn = np.linalg.norm(a, axis=1)
        if np.any(rn == 0.0) or not np.all(np.isfinite(a)) or not np.all(np.isfinite(b)):
            raise ValueError("a foothold's half-space rows must be finite and non-zero")
        a = a / rn[:, None]
        b = b / rn
        _freeze(self, a, b, n, off)

    @classmethod
    def from_polygon(cls, vertices_xy: np.ndarray, normal: Vector = (0.0, 0.0, 1.0),
                     offset: float = 0.0) -> Foothold:
        """Foothold from a convex 2D polygon in any order, lifted onto the plane n . p = d.

        The corners are sorted counter-clockwise about their mean (duplicates dropped); the
        half-spaces are vertical walls through the edges (A[:, 2] = 0)."""
        v = _convex_ccw(np.asarray(vertices_xy, dtype=float).reshape(-1, 2))
        edges = np.roll(v, -1, axis=0) - v
        out = np.column_stack([edges[:, 1], -edges[:, 0], np.zeros(len(v))])  # outward
        b = np.einsum("ij,ij->i", out[:, :2], v)
        fh = cls(out, b, np.asarray(normal, dtype=float), float(offset))
        # vertical walls: the horizontal projection is the polygon itself (fill the caches)
        v.setflags(write=False)
        fh.__dict__["vertices_xy"] = v
        fh.__dict__["halfspaces_xy"] = (fh.A[:, :2], fh.b)
        return fh

    @classmethod
    def from_ccw(cls, vertices_xy: np.ndarray, normal: Vector, offset: float) -> Foothold:
        """Foothold from a convex polygon whose corners run counter-clockwise seen from above.

        Row k of A is the outward unit normal of the edge from corner k to k + 1 (a vertical
        wall), b its offset through corner k; the corners and the plane are kept exactly as
        given, so the normal must already be unit length and point up (S3's fits, box tops).
        Raises ValueError for fewer than 3 corners, a repeated corner or no enclosed area."""
        v = np.array(vertices_xy, dtype=float)
        if v.ndim != 2 or v.shape[1] != 2:
            raise ValueError(f"a foothold polygon needs k >= 3 finite (x, y) corners, "
                             f"got an array of shape {v.shape}")
        return cls.many_from_ccw(v, (0, len(v)), np.reshape(normal, (1, -1)), (offset,))[0]

    @classmethod
    def many_from_ccw(cls, vertices_xy: np.ndarray, starts: Sequence[int] | np.ndarray,
                      normals: np.ndarray, offsets: Sequence[float] | np.ndarray
                      ) -> list[Foothold]:
        """``from_ccw`` for K polygons given back to back: polygon k's corners are
        ``vertices_xy[starts[k]:starts[k + 1]]``, its plane ``normals[k] . p = offsets[k]``.

        The same checks and rows as K calls of ``from_ccw``, each step one array operation
        for all polygons (a segmenter's few dozen polygons a map cost ~0.1 ms each in numpy's
        per-call overheads otherwise). Raises from_ccw's ValueError for the first polygon
        that fails, naming it when there are several."""
        v = np.array(vertices_xy, dtype=float)  # a copy: the footholds keep views of it
        s = np.asarray(starts, dtype=np.int64).reshape(-1)
        n = np.array(normals, dtype=float).reshape(-1, 3)
        d = np.asarray(offsets, dtype=float).reshape(-1)
        k = len(s) - 1
        if v.ndim != 2 or v.shape[1] != 2 or s[0] != 0 or s[-1] != len(v) or len(n) != k \
                or len(d) != k:
            raise ValueError(f"many_from_ccw needs (N, 2) corners split by K + 1 starts from 0 "
                             f"to N and K normals and offsets, got corners {v.shape}, "
                             f"{len(s)} starts, {len(n)} normals, {len(d)} offsets")
        if k == 0:
            return []
        sizes = np.diff(s)
        if np.any(sizes < 3):  # checked first: the steps below need three corners each
            bad = int(np.argmax(sizes < 3))
            raise ValueError(f"a foothold polygon needs k >= 3 finite (x, y) corners, got an "
                             f"array of shape {(int(sizes[bad]), 2)}{_which(bad, k)}")
        nxt = np.arange(1, len(v) + 1)
        nxt[s[1:] - 1] = s[:-1]  # each polygon's last corner closes on its first
        e = v[nxt] - v
        walls = np.column_stack((e[:, 1], -e[:, 0]))  # outward for counter-clockwise corners
        length = np.linalg.norm(walls, axis=1, keepdims=True)
        cross = v[:, 0] * v[nxt, 1] - v[nxt, 0] * v[:, 1]
        area = 0.5 * np.add.reduceat(cross, s[:-1])
        finite = np.logical_and.reduceat(np.isfinite(v).all(axis=1), s[:-1])
        unit_up = (np.isfinite(n).all(axis=1) & (np.abs(np.linalg.norm(n, axis=1) - 1.0) <= 1e-9)
                   & (n[:, 2] > 0.0))
        repeated = np.logical_or.reduceat(length[:, 0] == 0.0, s[:-1])
        failing = ~finite | ~unit_up | ~np.isfinite(d) | repeated | ~(area > 0.0)
        if failing.any():
            bad = int(np.argmax(failing))
            raise _ccw_error(v, s, n, d, bad, bool(unit_up[bad]), bool(repeated[bad]))
        walls /= length
        a = np.column_stack((walls, np.zeros(len(walls))))
        b = np.einsum("ij,ij->i", walls, v)
        out: list[Foothold] = []
        for i in range(k):  # one polygon each: only views and the fields remain
            lo, hi = s[i], s[i + 1]
            fh = object.__new__(cls)
            _freeze(fh, a[lo:hi], b[lo:hi], n[i], float(d[i]))
            vi = v[lo:hi]
            vi.setflags(write=False)
            fh.__dict__["vertices_xy"] = vi
            fh.__dict__["halfspaces_xy"] = (fh.A[:, :2], fh.b)
            out.append(fh)
        return out

    @classmethod
    def from_vertices(cls, vertices: np.ndarray) -> Foothold:
        """Foothold from the 3D corners of a planar convex polygon (plane by least squares)."""
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
        """2D half-spaces (F, c) of the horizontal projection, z eliminated by the plane."""
        beta, alpha = self.plane_xy
        f = self.A[:, :2] + np.outer(self.A[:, 2], beta)
        c = self.b - self.A[:, 2] * alpha
        nrm = np.linalg.norm(f, axis=1)
        keep = nrm > 1e-12
        return f[keep] / nrm[keep, None], c[keep] / nrm[keep]

    @cached_property
    def vertices_xy(self) -> np.ndarray:
        """Counter-clockwise 2D corners of the projection (empty (0, 2) if it is empty)."""
        f, c = self.halfspaces_xy
        return _vertices_from_halfspaces(f, c)

    @property
    def vertices(self) -> np.ndarray:
        """(k, 3) corners lifted onto the plane, counter-clockwise seen from above."""
        v = self.vertices_xy
        n = self.normal
        return np.column_stack((v, (self.offset - v @ n[:2]) / n[2]))

    @property
    def area_m2(self) -> float:
        """Area of the horizontal projection."""
        return signed_area(self.vertices_xy)

    def contains(self, p: Vector, tol: float = 1e-6) -> bool:
        """True when the 3D point p lies in the foothold (to ``tol`` metres)."""
        p = np.asarray(p, dtype=float)
        on_plane = abs(self.normal @ p - self.offset) <= tol
        return bool(np.all(self.A @ p <= self.b + tol) and on_plane)

    def contains_xy(self, x: float, y: float, tol: float = 1e-12) -> bool:
        """True when (x, y) lies in the horizontal projection (edges inside, to ``tol`` m)."""
        f, c = self.halfspaces_xy
        return bool(np.all(f @ np.array([x, y], dtype=float) <= c + tol))

    def height_at(self, p_xy: Vector) -> float:
        """z of the foothold plane above the horizontal point p_xy."""
        beta, alpha = self.plane_xy
        return float(alpha + beta @ np.asarray(p_xy, dtype=float)[:2])

    def eroded(self, half_x: float, half_y: float, yaw: float = 0.0) -> Foothold | None:
        """The centres of a ``2 half_x`` x ``2 half_y`` rectangle turned by ``yaw`` (a foot
        facing that heading; 0: +x) wholly inside this vertical-walled foothold, or None when
        it fits nowhere.

        The Minkowski difference of a convex polygon and a rectangle: each wall
        ``a . p <= b`` moves inwards by the rectangle's support ``half_x |a . u| + half_y
        |a . v|`` (u, v the foot's axes); the new corners are where neighbouring walls meet,
        so the rows must run along the edges in order (as ``from_ccw`` and ``from_polygon``
        make them)."""
        a = self.A
        if np.any(a[:, 2] != 0.0):
            raise ValueError("only a foothold with vertical walls (A[:, 2] = 0) can be eroded")
        c, s = math.cos(yaw), math.sin(yaw)
        along, across = a[:, 0] * c + a[:, 1] * s, a[:, 1] * c - a[:, 0] * s
        b = self.b - (half_x * np.abs(along) + half_y * np.abs(across))
        k = len(b)
        verts = np.zeros((k, 2))
        for i in range(k):
            (a0, a1), (c0, c1) = a[i - 1, :2], a[i, :2]
            det = a0 * c1 - a1 * c0
            if abs(det) < 1e-12:
                return None
            verts[i] = ((b[i - 1] * c1 - a1 * b[i]) / det, (a0 * b[i] - b[i - 1] * c0) / det)
        # a wall that vanished leaves corners outside the moved walls (or a flipped polygon
        # of no area): the rectangle does not fit
        if np.any(verts @ a[:, :2].T > b + 1e-9):
            return None
        if signed_area(verts) <= 1e-9:
            return None
        return Foothold.from_ccw(verts, self.normal, self.offset)


def signed_area(poly: np.ndarray | Sequence[Sequence[float]]) -> float:
    """Shoelace area of a 2D polygon: positive for counter-clockwise corners."""
    if len(poly) < 3:
        return 0.0
    pts = poly.tolist() if isinstance(poly, np.ndarray) else poly
    acc = 0.0
    x0, y0 = pts[-1]
    for x1, y1 in pts:  # a few dozen corners: plain Python beats numpy's call overhead
        acc += x0 * y1 - x1 * y0
        x0, y0 = x1, y1
    return 0.5 * acc


def _freeze(fh: Foothold, a: np.ndarray, b: np.ndarray, n: np.ndarray, offset: float) -> None:
    """Set a foothold's fields, read-only (the solver caches arrays by foothold identity)."""
    for arr in (a, b, n):
        arr.setflags(write=False)
    object.__setattr__(fh, "A", a)
    object.__setattr__(fh, "b", b)
    object.__setattr__(fh, "normal", n)
    object.__setattr__(fh, "offset", offset)


def _which(i: int, k: int) -> str:
    """' (polygon i of k)' when a batch holds several, else nothing."""
    return f" (polygon {i} of {k})" if k > 1 else ""


def _ccw_error(v: np.ndarray, s: np.ndarray, n: np.ndarray, d: np.ndarray, i: int,
               unit_up: bool, repeated: bool) -> ValueError:
    """from_ccw's error for polygon i of a batch: its first failing check, in from_ccw's order
    (corners, normal, offset, a repeated corner, area)."""
    c = v[s[i]:s[i + 1]]
    where = _which(i, len(s) - 1)
    if not np.all(np.isfinite(c)):
        return ValueError(f"a foothold polygon needs k >= 3 finite (x, y) corners, got an "
                          f"array of shape {c.shape}{where}")
    if not unit_up:
        return ValueError(f"from_ccw needs a unit normal pointing up, got {n[i]}{where}")
    if not np.isfinite(d[i]):
        return ValueError(f"a foothold's plane offset must be finite, got {d[i]}{where}")
    if repeated:
        return ValueError(f"a foothold polygon has a repeated corner: {c.tolist()}{where}")
    return ValueError(f"a foothold polygon must enclose an area counter-clockwise, got "
                      f"corners {c.tolist()}{where}")


def _convex_ccw(v: np.ndarray) -> np.ndarray:
    """Order the corners of a convex polygon counter-clockwise and drop duplicates."""
    centre = v.mean(axis=0)
    ang = np.arctan2(v[:, 1] - centre[1], v[:, 0] - centre[0])
    v = v[np.argsort(ang)]
    keep = np.linalg.norm(v - np.roll(v, 1, axis=0), axis=1) > 1e-12
    v = v[keep]
    if len(v) < 3:
        raise ValueError(f"a foothold polygon needs at least 3 distinct corners, got {len(v)}")
    return v


def _vertices_from_halfspaces(f: np.ndarray, c: np.ndarray, tol: float = 1e-9) -> np.ndarray:
    """Corners of {p : F p <= c} in 2D from all pairwise line intersections (k is small)."""
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
