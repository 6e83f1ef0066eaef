"""The DCM planner's terrain front end (Xiang et al., Section II-C, Alg. 3), on our elevation
map: steppable cells -> contours -> Ramer-Douglas-Peucker -> convex hull -> half-spaces, and
the velocity-adaptive selection of at most M_max regions. No LCM; the S3 process runs it in
S3's place (``params.method: contours``).

The paper thresholds "the heightmap" for steppable cells without saying on what; here a cell
is steppable when it is known, its slope (central differences) is below ``max_slope_deg`` and
the heights in its 3 x 3 neighbourhood span less than ``max_step_m`` (so a riser or a stone's
edge splits regions, as a threshold would), eroded by ``margin_px`` for the foot. Each
remaining contour above ``min_area_m2`` is simplified by RDP (``cv2.approxPolyDP``, tolerance
in cells: the paper ties it to the resolution), its convex hull taken (``cv2.convexHull``:
Sklansky's algorithm, as the paper's), and the region's plane fitted by least squares to its
cells. A hull may take in a little unsafe ground where the contour was not convex: the
paper's "small and controllable loss of geometric fidelity"; a hull less than ``min_fill``
the region's own cells is dropped (ours: the floor around a flight of stairs is a U whose
hull spans the treads).

Selection (when more than ``max_regions``): a rectangle along the walking direction from the
robot, shifted forward by the speed times ``beam_ahead_s`` and reaching ``beam_back_m`` behind
when the speed is below ``slow_mps`` (step-back room); the region under the robot is always
kept; the others that overlap the rectangle by ``min_overlap`` of their area (Sutherland-
Hodgman clipping, as the paper's) are kept nearest first. The walking direction and speed are
the map's own motion (ours: the map is centred on the robot, so its origin moves with it).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from runtime.geometry import Foothold
from runtime.params import spec


@dataclass(frozen=True)
class RegionParams:
    """Alg. 3's thresholds (the paper gives none; chosen for Cassie's foot and our map)."""

    max_slope_deg: float = spec(20.0, lo=0.0, hi=89.0, unit="deg")
    max_step_m: float = spec(0.03, lo=0.0, lo_open=True, unit="m")  # 3 x 3 height span
    margin_px: int = spec(2, lo=0, hi=20, unit="px")  # erosion for the foot
    min_area_m2: float = spec(0.02, lo=0.0, unit="m^2")  # smaller contours are dropped
    rdp_tolerance_px: float = spec(1.0, lo=0.0, unit="px")  # RDP tolerance, in cells
    max_edges: int = spec(12, lo=3, hi=64)  # the hull's edges (RDP tolerance doubled until)
    min_fill: float = spec(0.85, lo=0.0, hi=1.0)  # share of the hull that is the region's
    max_regions: int = spec(20, lo=1, hi=200)  # M_max, the planner's capacity
    beam_length_m: float = spec(1.6, lo=0.1, unit="m")
    beam_width_m: float = spec(1.0, lo=0.1, unit="m")
    beam_ahead_s: float = spec(1.0, lo=0.0, unit="s")  # forward shift = speed x this
    beam_back_m: float = spec(0.4, lo=0.0, unit="m")  # reach behind when slow
    slow_mps: float = spec(0.1, lo=0.0, unit="m/s")
    min_overlap: float = spec(0.3, lo=0.0, hi=1.0)  # share of a region's area in the beam
    velocity_time_constant_s: float = spec(0.5, lo=0.0, lo_open=True, unit="s")


def steppable_mask(elevation: np.ndarray, resolution: float, p: RegionParams) -> np.ndarray:
    """Known, gentle and locally flat cells (uint8 0/1), eroded by the margin."""
    e = np.asarray(elevation, dtype=np.float32)
    known = np.isfinite(e)
    gy, gx = np.gradient(np.where(known, e, np.float32(0.0)), resolution)
    slope_ok = np.hypot(gx, gy) < math.tan(math.radians(p.max_slope_deg))
    big = np.float32(1e6)  # an unknown neighbour makes the span huge (finite: no overflow)
    filled_hi = np.where(known, e, -big).astype(np.float32)
    filled_lo = np.where(known, e, big).astype(np.float32)
    k = np.ones((3, 3), np.uint8)
    span = cv2.dilate(filled_hi, k) - cv2.erode(filled_lo, k)
    flat = span < p.max_step_m
    # (so the map's holes bound regions too)
    mask = (known & slope_ok & flat).astype(np.uint8)
    if p.margin_px > 0:
        mask = cv2.erode(mask, np.ones((2 * p.margin_px + 1,) * 2, np.uint8))
    return mask


def extract_regions(elevation: np.ndarray, resolution: float, origin_xy: np.ndarray,
                    p: RegionParams) -> list[Foothold]:
    """Alg. 3's extraction: convex footholds (world frame) of the map's steppable contours.
    Rows run along y, columns along x, cell (0, 0)'s centre at ``origin_xy``."""
    e = np.asarray(elevation, dtype=np.float64)
    if e.ndim != 2 or e.size == 0:
        return []
    mask = steppable_mask(e, resolution, p)
    n, labels, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=4)
    out: list[Foothold] = []
    min_cells = p.min_area_m2 / (resolution * resolution)
    ox, oy = float(origin_xy[0]), float(origin_xy[1])
    for lab in range(1, n):
        c0, r0, w, h, cells = (int(v) for v in stats[lab])
        if cells < max(min_cells, 3):
            continue
        comp = (labels[r0:r0 + h, c0:c0 + w] == lab).astype(np.uint8)  # its bounding box
        rows, cols = np.nonzero(comp)
        rows, cols = rows + r0, cols + c0
        contours, _ = cv2.findContours(comp, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE,
                                       offset=(c0, r0))
        contour = max(contours, key=cv2.contourArea)
        tol = p.rdp_tolerance_px
        hull = cv2.convexHull(cv2.approxPolyDP(contour, tol, True))
        while len(hull) > p.max_edges:  # a bounded number of edges
            tol *= 2.0
            hull = cv2.convexHull(cv2.approxPolyDP(contour, tol, True))
        pix = hull.reshape(-1, 2).astype(np.float64)  # (col, row), cell centres
        if len(pix) < 3:
            continue
        # how much of the hull is the region's own ground (ours: the floor around a flight of
        # stairs is a U whose hull spans the treads at the floor's height; the MPFC stepped
        # into a riser on it, measured): below min_fill it is dropped
        area = np.zeros_like(comp)
        cv2.fillConvexPoly(area, hull.reshape(-1, 2) - np.array([c0, r0]), 1)
        if (area & comp).sum() < p.min_fill * max(int(area.sum()), 1):
            continue
        xy = np.column_stack([ox + pix[:, 0] * resolution, oy + pix[:, 1] * resolution])
        # the region's plane, z = a + b x + c y, least squares over its cells
        cx, cy, cz = ox + cols * resolution, oy + rows * resolution, e[rows, cols]
        a_mat = np.column_stack([np.ones_like(cx), cx, cy])
        (a, b, c), *_ = np.linalg.lstsq(a_mat, cz, rcond=None)
        normal = np.array([-b, -c, 1.0]) / math.sqrt(b * b + c * c + 1.0)
        try:
            out.append(Foothold.from_polygon(xy, tuple(normal), float(normal[2] * a)))
        except ValueError:  # a degenerate hull (a line of cells)
            continue
    return out


def _clip(poly: np.ndarray, rect: np.ndarray) -> np.ndarray:
    """Sutherland-Hodgman: ``poly`` (convex, any order) clipped by the convex CCW ``rect``."""
    out = poly
    for i in range(len(rect)):
        if len(out) == 0:
            break
        a, b = rect[i], rect[(i + 1) % len(rect)]
        edge = b - a
        side = edge[0] * (out[:, 1] - a[1]) - edge[1] * (out[:, 0] - a[0])  # >= 0: inside
        nxt = []
        for j in range(len(out)):
            p, q = out[j], out[(j + 1) % len(out)]
            sp, sq = side[j], side[(j + 1) % len(out)]
            if sp >= 0:
                nxt.append(p)
            if (sp >= 0) != (sq >= 0):
                nxt.append(p + (q - p) * (sp / (sp - sq)))
        out = np.array(nxt).reshape(-1, 2)
    return out


def _area(poly: np.ndarray) -> float:
    if len(poly) < 3:
        return 0.0
    x, y = poly[:, 0], poly[:, 1]
    return 0.5 * abs(float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))


def select_regions(regions: list[Foothold], robot_xy: np.ndarray, velocity_xy: np.ndarray,
                   p: RegionParams) -> list[Foothold]:
    """The velocity-adaptive beam mask: at most ``max_regions``, the one under the robot
    always, then those in the beam nearest first (module docstring)."""
    if len(regions) <= p.max_regions:
        return list(regions)
    robot = np.asarray(robot_xy, dtype=float)
    v = np.asarray(velocity_xy, dtype=float)
    speed = float(np.hypot(v[0], v[1]))
    d = v / speed if speed > 1e-6 else np.array([1.0, 0.0])
    side = np.array([-d[1], d[0]])
    back = p.beam_back_m if speed < p.slow_mps else 0.0
    start = -back + speed * p.beam_ahead_s
    lo, hi = start, start + p.beam_length_m + back
    w = 0.5 * p.beam_width_m
    rect = np.array([robot + lo * d - w * side, robot + hi * d - w * side,
                     robot + hi * d + w * side, robot + lo * d + w * side])
    dist = np.array([float(np.min(np.hypot(*(f.vertices_xy - robot).T))) for f in regions])
    under = [i for i, f in enumerate(regions) if f.contains_xy(robot[0], robot[1])]
    keep = [under[0] if under else int(np.argmin(dist))]
    for i in np.argsort(dist):
        if len(keep) >= p.max_regions:
            break
        if i in keep:
            continue
        v_xy = regions[i].vertices_xy
        if _area(_clip(v_xy, rect)) >= p.min_overlap * max(_area(v_xy), 1e-12):
            keep.append(int(i))
    return [regions[i] for i in keep]


class ContourRegions:
    """Alg. 3 per map: extract, then select by the map's motion (its origin follows the
    robot): what the S3 process publishes in S3's place."""

    def __init__(self, params: RegionParams) -> None:
        self.params = params
        self._last: tuple[float, np.ndarray] | None = None
        self.velocity = np.zeros(2)

    def process(self, elevation: np.ndarray, resolution: float, origin_xy: np.ndarray,
                map_time_s: float) -> list[Foothold]:
        """The map's regions, at most M_max of them."""
        e = np.asarray(elevation)
        origin = np.asarray(origin_xy, dtype=float)
        centre = origin + 0.5 * resolution * (np.array(e.shape[::-1], dtype=float) - 1.0)
        if self._last is not None and map_time_s > self._last[0]:
            dt = map_time_s - self._last[0]
            a = min(dt / self.params.velocity_time_constant_s, 1.0)
            self.velocity += a * ((centre - self._last[1]) / dt - self.velocity)
        self._last = (map_time_s, centre)
        regions = extract_regions(e, resolution, origin, self.params)
        return select_regions(regions, centre, self.velocity, self.params)
