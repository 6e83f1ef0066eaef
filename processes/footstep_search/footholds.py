"""The MPFC's footholds as padded arrays: the world set once per foothold set, the stance-frame
pruning per solve (Section IV-C).

The footholds themselves are ``runtime.geometry.Foothold``: unit half-space rows and a unit
normal, so that the big-M of (20) relaxes every row by M metres. Because neither the ALIP
dynamics nor the costs depend on footstep height (R has a zero z weight), the search works on
their horizontal projections (``Foothold.halfspaces_xy``, ``Foothold.vertices_xy``); the 3D
rows and planes stay for the big-M form (20).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from runtime.geometry import Foothold


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


class FootholdCache:
    """The ``WorldFootholds`` of the newest foothold list, rebuilt only when the list changes
    (by the footholds' identity: the process keeps the same objects while S3's set stands)."""

    def __init__(self, min_normal_z: float) -> None:
        self.min_normal_z = min_normal_z
        self._world: WorldFootholds | None = None
        self._key: tuple[int, ...] = ()

    def world(self, footholds: list[Foothold]) -> WorldFootholds:
        key = tuple(id(f) for f in footholds)
        if self._world is None or key != self._key:
            self._world = WorldFootholds(footholds, self.min_normal_z)
            self._key = key
        return self._world


def shifted_incumbent(prev_indices: tuple[int, ...] | None, prev_stance: str, stance: str,
                      lf: LocalFootholds) -> tuple[int, ...] | None:
    """The previous solve's foothold assignment (caller indices), mapped to this solve's pruned
    list by the foothold identity, shifted by one step after a touchdown; None when a foothold
    of it is not in this solve's list."""
    if prev_indices is None or lf.count == 0:
        return None
    where = {int(g): k for k, g in enumerate(lf.index)}
    prev_idx = list(prev_indices)
    if prev_stance != stance:  # touchdown happened: p_2 became p_1
        prev_idx = prev_idx[1:] + prev_idx[-1:]
    out = []
    for g in prev_idx:
        if g not in where:
            return None
        out.append(where[g])
    return tuple(out)
