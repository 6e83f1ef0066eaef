"""Candidate contacts of the SLIP planner (Bartlett & Manchester, Sections II-A, III-B): every
surface point within reach is a candidate force, each with a traversability cost C.

Points come from the stack's terrain in one of two forms: the footholds (``Foothold``
polygons, S3's or the sim's ground truth), sampled on a grid; or the elevation map's cells,
with S3's safety score as the cost map. Per time step, the K nearest points within the reach
R of the CoM's nominal position are its candidates (the paper's RKNN search), found with
scipy's cKDTree: one tree over the few thousand points (an elevation map's tens of
thousands) finds every point within reach of all N centres in one call, in O(log M) each,
where a brute-force N x M distance matrix grows with the map; scipy is already a
dependency.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from runtime.geometry import Foothold


@dataclass(frozen=True)
class Candidates:
    """Surface points that may push on the CoM: positions (M, 3), unit upward surface normals
    (M, 3) and the cost C of (6) per point (M,), 1 on the safest terrain."""

    points: np.ndarray
    normals: np.ndarray
    cost: np.ndarray

    def __len__(self) -> int:
        return len(self.points)


@dataclass(frozen=True)
class CostMap:
    """S3's safety score on the elevation map's grid (rows y, columns x, as
    ``elevation_map_t``), in [0, 1] (``processes.s3.segmentation.Segmenter.score``); the
    traversability cost of (6) is ``1 + cost_unsafe (1 - score)``, and off the map or on an
    unknown (NaN) cell the score is taken as 0 (unseen is not safe)."""

    score: np.ndarray
    origin_xy: tuple[float, float]  # the world (x, y) of cell [0, 0]'s centre
    resolution_m: float

    def score_at(self, xy: np.ndarray) -> np.ndarray:
        """The score of the cell under each (x, y) of ``xy`` (M, 2), nearest cell."""
        xy = np.asarray(xy, dtype=float).reshape(-1, 2)
        col = np.rint((xy[:, 0] - self.origin_xy[0]) / self.resolution_m).astype(int)
        row = np.rint((xy[:, 1] - self.origin_xy[1]) / self.resolution_m).astype(int)
        rows, cols = self.score.shape
        inside = (row >= 0) & (row < rows) & (col >= 0) & (col < cols)
        out = np.zeros(len(xy))
        out[inside] = self.score[row[inside], col[inside]]
        return np.nan_to_num(np.clip(out, 0.0, 1.0), nan=0.0)

    def cost_at(self, xy: np.ndarray, cost_unsafe: float) -> np.ndarray:
        """C of (6) at each point: 1 where S3 finds it safe, up to 1 + ``cost_unsafe``."""
        return 1.0 + cost_unsafe * (1.0 - self.score_at(xy))


def sample_footholds(footholds: Sequence[Foothold], spacing_m: float,
                     bounds_xy: tuple[float, float, float, float] | None = None,
                     cost_map: CostMap | None = None, cost_unsafe: float = 0.0) -> Candidates:
    """Every foothold polygon sampled on a world-aligned grid of ``spacing_m`` (points on the
    same grid whichever foothold they fall in, so a point is the same point between plans),
    within ``bounds_xy`` = (x_min, x_max, y_min, y_max) when given; z and the normal from the
    foothold's plane; cost 1, or the cost map's."""
    pts, nrm = [], []
    for fh in footholds:
        v = fh.vertices_xy
        if len(v) < 3:
            continue
        lo, hi = v.min(axis=0), v.max(axis=0)
        if bounds_xy is not None:
            lo = np.maximum(lo, (bounds_xy[0], bounds_xy[2]))
            hi = np.minimum(hi, (bounds_xy[1], bounds_xy[3]))
            if np.any(lo > hi):
                continue
        ix = np.arange(np.ceil(lo[0] / spacing_m), np.floor(hi[0] / spacing_m) + 1)
        iy = np.arange(np.ceil(lo[1] / spacing_m), np.floor(hi[1] / spacing_m) + 1)
        gx, gy = np.meshgrid(ix * spacing_m, iy * spacing_m, indexing="ij")
        xy = np.column_stack([gx.ravel(), gy.ravel()])
        f, c = fh.halfspaces_xy
        xy = xy[np.all(xy @ f.T <= c + 1e-9, axis=1)]
        if len(xy) == 0:
            continue
        beta, alpha = fh.plane_xy
        pts.append(np.column_stack([xy, alpha + xy @ beta]))
        nrm.append(np.broadcast_to(fh.normal, (len(xy), 3)))
    if not pts:
        return Candidates(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0))
    points = np.vstack(pts)
    cost = (cost_map.cost_at(points[:, :2], cost_unsafe) if cost_map is not None
            else np.ones(len(points)))
    return Candidates(points, np.vstack(nrm), cost)


def sample_elevation_map(elevation: np.ndarray, origin_xy: tuple[float, float],
                         resolution_m: float, score: np.ndarray | None = None,
                         k_safe: float = 0.0, stride: int = 1, cost_unsafe: float = 0.0
                         ) -> Candidates:
    """The elevation map's cells as candidates (every ``stride``-th row and column): known
    cells, with S3's score above ``k_safe`` when a score is given; the normal from the map's
    gradient, the cost from the score (the paper's "terrain cost map")."""
    e = np.asarray(elevation, dtype=float)
    gy, gx = np.gradient(e, resolution_m)
    rows, cols = np.mgrid[0:e.shape[0]:stride, 0:e.shape[1]:stride]
    rows, cols = rows.ravel(), cols.ravel()
    ok = np.isfinite(e[rows, cols]) & np.isfinite(gx[rows, cols]) & np.isfinite(gy[rows, cols])
    if score is not None:
        ok &= np.nan_to_num(score[rows, cols], nan=0.0) > k_safe
    rows, cols = rows[ok], cols[ok]
    xy = np.column_stack([origin_xy[0] + cols * resolution_m,
                          origin_xy[1] + rows * resolution_m])
    n = np.column_stack([-gx[rows, cols], -gy[rows, cols], np.ones(len(rows))])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    cost = (CostMap(score, origin_xy, resolution_m).cost_at(xy, cost_unsafe)
            if score is not None else np.ones(len(xy)))
    return Candidates(np.column_stack([xy, e[rows, cols]]), n, cost)


def nearest_within_reach(cands: Candidates, centres: np.ndarray, k: int, reach_m: float
                         ) -> tuple[np.ndarray, np.ndarray]:
    """The RKNN search of Section II-A: for each centre (N, 3) (the nominal CoM of a time
    step), its ``k`` nearest candidate points among those within ``reach_m`` of it.
    "Nearest" is horizontal (ours: the paper does not say): in 3D the points nearest a CoM
    0.85 m up are the highest ones, a stair ahead before the ground under the CoM, where a
    leg's reach is a sphere and its swing a horizontal move. Returns (step, point), the flat
    index pairs of every (time step, candidate) kept, ordered by step then distance."""
    centres = np.asarray(centres, float).reshape(-1, 3)
    if len(cands) == 0:
        return np.zeros(0, dtype=int), np.zeros(0, dtype=int)
    tree = cKDTree(cands.points[:, :2])
    within = tree.query_ball_point(centres[:, :2], reach_m)  # a disc holds the sphere
    steps, points = [], []
    for i, idx in enumerate(within):  # N lists, each ranked with array ops
        idx = np.asarray(idx, dtype=int)
        d3 = np.linalg.norm(cands.points[idx] - centres[i], axis=1)
        idx = idx[d3 <= reach_m]
        d2 = np.linalg.norm(cands.points[idx, :2] - centres[i, :2], axis=1)
        keep = idx[np.lexsort((idx, d2))][:k]  # ties by index: deterministic
        steps.append(np.full(len(keep), i))
        points.append(keep)
    return np.concatenate(steps).astype(int), np.concatenate(points).astype(int)


def in_friction_cone(leg: np.ndarray, normals: np.ndarray, mu: float) -> np.ndarray:
    """The prefilter of Section III-B: with the force along the approximate leg vector
    s~ - f_p (13), the force's direction is known before the QP, so (3) is a test per
    candidate: a normal component a_n > 0 and a tangential one no larger than mu a_n."""
    an = np.einsum("ij,ij->i", leg, normals)
    at = np.linalg.norm(leg - an[:, None] * normals, axis=1)
    return (an > 0.0) & (at <= mu * an)


def surface_height(footholds: Sequence[Foothold], xy: np.ndarray) -> np.ndarray:
    """The highest foothold plane over each (x, y) of ``xy`` (M, 2); NaN where none is."""
    xy = np.asarray(xy, dtype=float).reshape(-1, 2)
    z = np.full(len(xy), -np.inf)
    for fh in footholds:
        f, c = fh.halfspaces_xy
        inside = np.all(xy @ f.T <= c + 1e-9, axis=1)
        beta, alpha = fh.plane_xy
        z = np.where(inside, np.maximum(z, alpha + xy @ beta), z)
    return np.where(np.isfinite(z), z, np.nan)
