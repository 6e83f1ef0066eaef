"""Robot-centric elevation map (Section VII-B; Fankhauser et al. [31]): a grid with a per-cell
Kalman height update, leg cropping and the stance-foot z-drift correction.

Grid convention (that of `lcmtypes/elevation_map_t`): cell (i, j), row i and column j, has its
centre at world (x, y) = origin + (j * resolution, i * resolution); rows run along +y, columns
along +x. NaN marks a cell never measured. No threads and no LCM here: the perception process
shell owns the camera polling thread and the messages.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from runtime.errors import ConfigError
from runtime.params import check, spec


@dataclass(frozen=True)
class ElevationMapParams:
    """Elevation-map parameters (Table VIII, elevation mapping; the noise model is ours)."""

    length_m: float = spec(2.5, lo=0.1, hi=20.0, lo_open=True, unit="m")
    resolution_m: float = spec(0.025, lo=0.005, hi=0.5, unit="m")
    min_depth_m: float = spec(0.2, lo=0.0, hi=10.0, unit="m")
    max_depth_m: float = spec(3.0, lo=0.1, hi=20.0, unit="m")
    decimation: int = spec(2, lo=1, hi=16, unit="px")
    sensor_noise_base_m: float = spec(0.003, lo=0.0, hi=1.0, lo_open=True, unit="m")
    sensor_noise_quadratic_per_m: float = spec(0.002, lo=0.0, hi=1.0, unit="1/m")
    min_variance_m2: float = spec(1e-6, lo=0.0, hi=1.0, lo_open=True, unit="m^2")
    max_variance_m2: float = spec(0.01, lo=0.0, hi=100.0, lo_open=True, unit="m^2")
    mahalanobis_threshold: float = spec(2.5, lo=0.0, hi=100.0, lo_open=True)
    surface_gate_sigma: float = spec(3.0, lo=0.0, hi=1e6, lo_open=True)
    multi_height_noise_m2: float = spec(9e-7, lo=0.0, hi=1.0, unit="m^2")
    #: variance added to a cell whose rejected measurement lies above it (ours)
    obstacle_variance_m2: float = spec(0.0, lo=0.0, hi=1.0, unit="m^2")
    process_noise_m2: float = spec(0.0, lo=0.0, hi=1.0, unit="m^2 per update")
    drift_patch_px: int = spec(4, lo=1, hi=32, unit="px")
    # the ground the robot starts on, from its feet (0: off); see ElevationMap.initialize_submap
    init_submap_back_m: float = spec(0.0, lo=0.0, hi=5.0, unit="m")
    init_submap_front_m: float = spec(0.0, lo=0.0, hi=5.0, unit="m")
    init_submap_half_y_m: float = spec(0.0, lo=0.0, hi=5.0, unit="m")

    @property
    def cells(self) -> int:
        """Cells per side of the square grid."""
        return max(1, round(self.length_m / self.resolution_m))

    def __post_init__(self) -> None:
        """The checks across fields (the ranges of single fields are ``spec``'s)."""
        if self.max_depth_m <= self.min_depth_m:
            raise ConfigError("<ElevationMapParams>", "max_depth_m", "must exceed min_depth_m",
                              f"> {self.min_depth_m:g} m")
        if self.max_variance_m2 < self.min_variance_m2:
            raise ConfigError("<ElevationMapParams>", "max_variance_m2",
                              "must be >= min_variance_m2", f">= {self.min_variance_m2:g} m^2")


@dataclass(frozen=True)
class CropBox:
    """An oriented box in world coordinates (a leg link's bound): points inside are dropped."""

    center: np.ndarray          # (3,) world position of the box centre
    rotation: np.ndarray        # (3, 3) world-from-box rotation
    half_extents: np.ndarray    # (3,) half side lengths along the box axes


# --- geometry helpers -------------------------------------------------------------------------

def quat_to_rotmat(quat_wxyz: Sequence[float] | np.ndarray) -> np.ndarray:
    """Rotation matrix of a (w, x, y, z) quaternion (normalised here)."""
    w, x, y, z = np.asarray(quat_wxyz, dtype=float) / np.linalg.norm(quat_wxyz)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])


@functools.lru_cache(maxsize=8)
def _pixel_rays(height: int, width: int, fx: float, fy: float, cx: float, cy: float,
                stride: int) -> tuple[np.ndarray, np.ndarray]:
    """Normalised image coordinates (x/z, y/z) of the decimated pixel grid, cached per camera."""
    v, u = np.mgrid[0:height:stride, 0:width:stride]
    rx = ((u - cx) / fx).astype(np.float64)
    ry = ((v - cy) / fy).astype(np.float64)
    rx.setflags(write=False)
    ry.setflags(write=False)
    return rx, ry


def backproject(depth_m: np.ndarray, fx: float, fy: float, cx: float, cy: float,
                stride: int = 1, min_depth_m: float = 0.0,
                max_depth_m: float = np.inf) -> np.ndarray:
    """Pinhole back-projection of a depth image to (N, 3) points in the optical frame.

    Optical frame: z forward, x right, y down. Pixels with no depth (0, NaN) or outside
    [min_depth_m, max_depth_m] are dropped; `stride` decimates as the RealSense filter does.
    """
    depth = np.asarray(depth_m)
    if depth.ndim != 2 or depth.size == 0:
        return np.empty((0, 3))
    h, w = depth.shape
    rx, ry = _pixel_rays(h, w, float(fx), float(fy), float(cx), float(cy), int(stride))
    z = depth[::stride, ::stride]
    with np.errstate(invalid="ignore"):
        ok = np.isfinite(z) & (z > max(min_depth_m, 0.0)) & (z <= max_depth_m)
    zs = z[ok].astype(np.float64)
    return np.column_stack((rx[ok] * zs, ry[ok] * zs, zs))


def transform_points(points: np.ndarray, position: Sequence[float] | np.ndarray,
                     quat_wxyz: Sequence[float] | np.ndarray) -> np.ndarray:
    """World points p_w = R(q) p + position for (N, 3) points in the camera frame."""
    rot = quat_to_rotmat(quat_wxyz)
    return points @ rot.T + np.asarray(position, dtype=float)


def crop_boxes(points: np.ndarray, boxes: Sequence[CropBox]) -> np.ndarray:
    """Boolean mask of the (N, 3) points outside every box (Section VII-B: crop the legs)."""
    keep = np.ones(points.shape[0], dtype=bool)
    for box in boxes:  # a handful of leg links; vectorised over points
        local = (points - np.asarray(box.center)) @ np.asarray(box.rotation)
        inside = np.all(np.abs(local) <= np.asarray(box.half_extents), axis=1)
        keep &= ~inside
    return keep


# --- the map ----------------------------------------------------------------------------------

class ElevationMap:
    """Robot-centred grid of height estimates and their variances (Fankhauser et al.).

    Layers: `elevation` (m, NaN unknown), `variance` (m^2, NaN unknown), `time` (s of the
    last fused measurement, NaN never) and `lowest` (m, the lowest point the latest frame that
    saw the cell put in it: the visible depth of a riser or of a gap's far wall, which S3's
    least-neighbouring-value inpainting uses to keep occluded gaps low). The grid moves in
    whole cells so no resampling blurs it.
    """

    LAYERS = ("elevation", "variance", "time", "lowest")

    def __init__(self, params: ElevationMapParams | None = None) -> None:
        self.params = params if params is not None else ElevationMapParams()
        check(self.params)
        n = self.params.cells
        self.resolution = float(self.params.resolution_m)
        self.shape = (n, n)
        self.elevation = np.full(self.shape, np.nan)
        self.variance = np.full(self.shape, np.nan)
        self.time = np.full(self.shape, np.nan)
        self.lowest = np.full(self.shape, np.nan)
        #: 1 where the height is the initial submap's prior, not a measurement (else 0 or NaN)
        self.prior = np.zeros(self.shape)
        self._scratch = np.empty(self.shape)
        # centre of cell (0, 0); the map centre starts at the world origin
        self.origin = -0.5 * (n - 1) * self.resolution * np.ones(2)

    # -- indexing --
    @property
    def center(self) -> np.ndarray:
        """World xy of the grid centre."""
        return self.origin + 0.5 * (self.shape[0] - 1) * self.resolution

    @property
    def layers(self) -> dict[str, np.ndarray]:
        """Named layers, in message order."""
        return {"elevation": self.elevation, "variance": self.variance, "time": self.time,
                "lowest": self.lowest}

    def world_to_index(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(rows, cols, inside) of the cells holding world points xy (N, 2); nearest centre."""
        xy = np.asarray(xy, dtype=float).reshape(-1, 2)
        u = np.floor((xy - self.origin) / self.resolution + 0.5)
        u[~np.isfinite(u) | (np.abs(u) > 2**40)] = -1.0      # NaN/inf/far points: outside
        ij = u.astype(np.int64)
        cols, rows = ij[:, 0], ij[:, 1]
        inside = (rows >= 0) & (rows < self.shape[0]) & (cols >= 0) & (cols < self.shape[1])
        return rows, cols, inside

    def cell_centers(self) -> tuple[np.ndarray, np.ndarray]:
        """World x and y of every cell centre, each (rows, cols)."""
        r, c = np.indices(self.shape)
        return self.origin[0] + c * self.resolution, self.origin[1] + r * self.resolution

    def clear(self) -> None:
        """Forget every measurement."""
        for layer in (self.elevation, self.variance, self.time, self.lowest):
            layer.fill(np.nan)
        self.prior.fill(0.0)

    # -- motion --
    def recenter(self, xy: Sequence[float] | np.ndarray) -> tuple[int, int]:
        """Move the grid so its centre is the cell nearest `xy`; returns the (rows, cols) shift.

        Cells that stay in view keep their values; cells that enter are unknown (NaN).
        """
        res = self.resolution
        target = np.asarray(xy, dtype=float)[:2]
        shift = np.round((target - self.center) / res).astype(int)  # (dx cells, dy cells)
        dc, dr = int(shift[0]), int(shift[1])
        if dr == 0 and dc == 0:
            return 0, 0
        for layer in (self.elevation, self.variance, self.time, self.lowest, self.prior):
            _shift_into(layer, dr, dc, self._scratch)
        self.origin = self.origin + np.array([dc, dr]) * res
        return dr, dc

    # -- measurement update --
    def sensor_variance(self, depth_m: np.ndarray) -> np.ndarray:
        """Per-point height variance of a stereo camera, whose error grows with the square of
        the depth along the optical axis: sigma = a + b z^2."""
        p = self.params
        sigma = p.sensor_noise_base_m + p.sensor_noise_quadratic_per_m * np.square(depth_m)
        return np.square(sigma)

    def integrate_points(self, points_world: np.ndarray,
                         variance_m2: float | np.ndarray | None = None,
                         time_s: float | None = None) -> int:
        """Fuse (N, 3) world points into the grid with a per-cell Kalman update; returns the
        number of cells updated.

        Each frame's points in one cell are first combined by inverse-variance weighting
        (np.bincount), which equals fusing them one by one, after dropping those more than
        `surface_gate_sigma` standard deviations below the cell's highest point (the terrain's
        top surface, not a riser seen edge-on); then one scalar Kalman update per cell.
        A measurement farther than the Mahalanobis threshold is not fused: the cell's variance
        grows by the multi-height noise instead (Fankhauser et al.), and a cell whose variance
        exceeds the ceiling is reset, so a moved obstacle is eventually replaced. Unknown cells
        take the measurement as is.
        """
        pts = np.asarray(points_world, dtype=float).reshape(-1, 3)
        return self._fuse(pts, variance_m2, time_s, check_finite=True)

    def _fuse(self, pts: np.ndarray, variance_m2: float | np.ndarray | None,
              time_s: float | None, check_finite: bool) -> int:
        """integrate_points without the conversions; finite input may skip the check."""
        p = self.params
        if p.process_noise_m2 > 0.0:
            np.add(self.variance, p.process_noise_m2, out=self.variance)
            with np.errstate(invalid="ignore"):
                expired = self.variance > p.max_variance_m2
            self.elevation[expired] = np.nan
            self.variance[expired] = np.nan
            self.lowest[expired] = np.nan
        if pts.shape[0] == 0:
            return 0
        if check_finite:
            rows, cols, inside = self.world_to_index(pts[:, :2])
            sel = inside & np.isfinite(pts[:, 2])
        else:
            ij = np.floor((pts[:, :2] - self.origin) * (1.0 / self.resolution) + 0.5)
            ij = ij.astype(np.int64)
            cols, rows = ij[:, 0], ij[:, 1]
            sel = (rows >= 0) & (rows < self.shape[0]) & (cols >= 0) & (cols < self.shape[1])
        if not np.any(sel):
            return 0
        if variance_m2 is None:
            var = np.full(pts.shape[0], p.sensor_noise_base_m ** 2)
        else:
            var = np.broadcast_to(np.asarray(variance_m2, dtype=float), (pts.shape[0],))
        var = np.maximum(var[sel], p.min_variance_m2)
        flat = rows[sel] * self.shape[1] + cols[sel]
        z = pts[sel, 2]
        n = self.shape[0] * self.shape[1]
        # top surface: drop points more than `surface_gate_sigma` below the cell's highest point
        # this frame (a riser or a stone's side seen obliquely would drag the edge cells down)
        z_top = np.full(n, -np.inf)
        np.maximum.at(z_top, flat, z)
        z_low = np.full(n, np.inf)
        np.minimum.at(z_low, flat, z)
        hit = np.isfinite(z_low)
        self.lowest.reshape(-1)[hit] = z_low[hit]
        top = z >= z_top[flat] - p.surface_gate_sigma * np.sqrt(var)
        flat, z, var = flat[top], z[top], var[top]
        w = 1.0 / var
        w_sum = np.bincount(flat, weights=w, minlength=n)
        wz_sum = np.bincount(flat, weights=w * z, minlength=n)
        cells = np.flatnonzero(w_sum)
        z_m = wz_sum[cells] / w_sum[cells]
        var_m = 1.0 / w_sum[cells]

        elev = self.elevation.reshape(-1)
        varl = self.variance.reshape(-1)
        h = elev[cells]
        v = varl[cells]
        prior = self.prior.reshape(-1)
        # a cell holding only the initial submap's prior takes the measurement as it is
        new = np.isnan(h) | (prior[cells] == 1.0)
        prior[cells] = 0.0
        with np.errstate(invalid="ignore"):
            mahal = np.abs(z_m - h) / np.sqrt(v + var_m)
        fuse = ~new & (mahal <= p.mahalanobis_threshold)
        reject = ~new & ~fuse
        # scalar Kalman update, gain K = v / (v + var_m)
        h_f, v_f, zf, vmf = h[fuse], v[fuse], z_m[fuse], var_m[fuse]
        gain = v_f / (v_f + vmf)
        h[fuse] = h_f + gain * (zf - h_f)
        v[fuse] = (1.0 - gain) * v_f
        h[new] = z_m[new]
        v[new] = var_m[new]
        v[reject] += p.multi_height_noise_m2
        # Something now stands on a cell the map knows well (a dropped or moved obstacle):
        # the measurement is far above it and rejected, and multi_height_noise alone would
        # take thousands of frames to let it in (measured: a 15 cm cube dropped 0.9 m ahead
        # never showed). A rejected measurement *above* the cell opens it up (as
        # elevation_mapping_cupy's outlier variance does), so the next frame's measurement
        # decides: the obstacle is in the map one frame later, a lone outlier is not.
        if p.obstacle_variance_m2 > 0.0:  # (to the ceiling at most: the cell stays known)
            up = reject & (z_m > h)
            v[up] = np.minimum(v[up] + p.obstacle_variance_m2, p.max_variance_m2)
        np.maximum(v, p.min_variance_m2, out=v)
        # a cell whose variance outgrew the ceiling is reset to unknown: the next measurement
        # re-initialises it (how a moved obstacle or a stale outlier leaves the map)
        expired = v > p.max_variance_m2
        h[expired] = np.nan
        v[expired] = np.nan
        self.lowest.reshape(-1)[cells[expired]] = np.nan
        elev[cells] = h
        varl[cells] = v
        if time_s is not None:
            tl = self.time.reshape(-1)
            tl[cells[~reject]] = time_s
        return int(cells.size)

    def update_from_depth(self, depth_m: np.ndarray, fx: float, fy: float, cx: float, cy: float,
                          camera_pos: Sequence[float] | np.ndarray,
                          camera_quat_wxyz: Sequence[float] | np.ndarray,
                          leg_boxes: Sequence[CropBox] = (),
                          time_s: float | None = None) -> str:
        """Back-project, transform with the camera pose, crop the legs, fuse; returns a status.

        Status: 'ok', 'bad intrinsics', 'bad camera pose', 'no valid depth' (no pixel in
        range), 'all points cropped' or 'no points in map'; the map is unchanged unless the
        status is 'ok'.
        """
        p = self.params
        intr = np.array([fx, fy, cx, cy], dtype=float)
        if not np.all(np.isfinite(intr)) or fx <= 0.0 or fy <= 0.0:
            return "bad intrinsics"
        pos = np.asarray(camera_pos, dtype=float).reshape(-1)
        quat = np.asarray(camera_quat_wxyz, dtype=float).reshape(-1)
        if pos.size != 3 or quat.size != 4 or not np.all(np.isfinite(pos)) or \
                not np.all(np.isfinite(quat)) or np.linalg.norm(quat) < 1e-9:
            return "bad camera pose"
        pts_c = backproject(depth_m, fx, fy, cx, cy, p.decimation, p.min_depth_m, p.max_depth_m)
        if pts_c.shape[0] == 0:
            return "no valid depth"
        depth = pts_c[:, 2]
        pts_w = transform_points(pts_c, pos, quat)
        if leg_boxes:
            keep = crop_boxes(pts_w, leg_boxes)
            if not np.any(keep):
                return "all points cropped"
            pts_w, depth = pts_w[keep], depth[keep]
        # back-projected points are finite by construction: skip the per-point check
        updated = self._fuse(pts_w, self.sensor_variance(depth), time_s, check_finite=False)
        return "ok" if updated > 0 else "no points in map"

    # -- drift correction --
    def initialize_submap(self, center_xy: Sequence[float] | np.ndarray, z: float,
                          yaw: float = 0.0) -> int:
        """Fill the unknown cells of a rectangle around the robot's feet with their height, as
        the initial submap of Fankhauser's elevation mapping: the camera looks ahead, so the
        ground the robot starts on is otherwise never seen, and an inpainting of it from far
        rims (LNV takes the lowest: a pit's floor) would put the robot's own footing in a hole.

        The rectangle reaches ``init_submap_back_m`` behind the feet and
        ``init_submap_front_m`` ahead of them (along ``yaw``), and ``init_submap_half_y_m`` to
        either side; ahead it stops where the camera starts to see the ground, so that it never
        claims ground the camera cannot check (past an edge just ahead, the pit's floor is
        occluded by the edge). Its cells are marked as a prior, which the first camera
        measurement of the cell replaces (no Kalman fusion, no Mahalanobis gate), and get half
        the largest variance. Cells already known keep their values. Returns the number of
        cells filled."""
        p = self.params
        back, front, hy = p.init_submap_back_m, p.init_submap_front_m, p.init_submap_half_y_m
        c = np.asarray(center_xy, dtype=float).reshape(-1)[:2]
        if back + front <= 0.0 or hy <= 0.0 or not (np.all(np.isfinite(c)) and np.isfinite(z)):
            return 0
        x, y = self.cell_centers()
        cy, sy = np.cos(yaw), np.sin(yaw)
        dx, dy = x - c[0], y - c[1]
        along = cy * dx + sy * dy
        inside = (along >= -back) & (along <= front) & (np.abs(-sy * dx + cy * dy) <= hy)
        fill = inside & np.isnan(self.elevation)
        self.elevation[fill] = z
        self.variance[fill] = 0.5 * p.max_variance_m2
        self.prior[fill] = 1.0
        return int(np.count_nonzero(fill))

    def apply_drift_correction(self, contact_point_world: Sequence[float] | np.ndarray
                               ) -> float | None:
        """Shift the whole map so its height at the stance foot equals the foot's height.

        Section VII-B: before each point-cloud update, add (foot z - map z) to every cell, the
        map height being the median of a 4 x 4 patch centred at the contact point (robust to
        outliers). Returns the offset applied, or None when the patch holds no known cell.
        """
        c = np.asarray(contact_point_world, dtype=float).reshape(-1)
        if c.size != 3 or not np.all(np.isfinite(c)):
            return None
        k = self.params.drift_patch_px
        u = (c[:2] - self.origin) / self.resolution + 0.5  # cell units, cell j spans [j, j+1)
        start = np.round(u - 0.5 * k).astype(int)
        c0, r0 = int(start[0]), int(start[1])
        r_lo, r_hi = max(r0, 0), min(r0 + k, self.shape[0])
        c_lo, c_hi = max(c0, 0), min(c0 + k, self.shape[1])
        if r_lo >= r_hi or c_lo >= c_hi:
            return None
        patch = self.elevation[r_lo:r_hi, c_lo:c_hi]
        vals = patch[np.isfinite(patch)]
        if vals.size == 0:
            return None
        offset = float(c[2] - np.median(vals))
        np.add(self.elevation, offset, out=self.elevation)
        np.add(self.lowest, offset, out=self.lowest)
        return offset


def _shift_into(layer: np.ndarray, dr: int, dc: int, scratch: np.ndarray) -> None:
    """Move the grid content by (-dr, -dc) cells in place (the window moved by +dr, +dc)."""
    rows, cols = layer.shape
    scratch.fill(np.nan)
    if abs(dr) < rows and abs(dc) < cols:
        src_r = slice(max(dr, 0), rows + min(dr, 0))
        dst_r = slice(max(-dr, 0), rows + min(-dr, 0))
        src_c = slice(max(dc, 0), cols + min(dc, 0))
        dst_c = slice(max(-dc, 0), cols + min(-dc, 0))
        scratch[dst_r, dst_c] = layer[src_r, src_c]
    layer[...] = scratch
