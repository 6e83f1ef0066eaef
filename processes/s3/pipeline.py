"""The S3 pipeline (Fig. 7): elevation map -> inpainting -> S3 mask -> convex decomposition ->
planar footholds, with per-stage times and a status that says why a frame gave nothing.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from processes.s3.decomposition import convex_decomposition
from processes.s3.params import S3Params
from processes.s3.planes import fit_planes
from processes.s3.segmentation import Segmenter, inpaint, shift_mask
from runtime.geometry import Foothold
from runtime.params import check

STAGES = ("inpainting", "criteria", "cleanup", "decomposition", "plane_fit")

STATUS_OK = "ok"
STATUS_NO_SAFE = "no safe terrain"
STATUS_EMPTY = "empty map"
STATUS_ALL_NAN = "all NaN"
STATUS_STALE = "stale map"
STATUS_BAD = "bad input"


@dataclass
class S3Result:
    """One frame's output: the safe mask, the footholds (world frame, Section IV-C), per-stage
    times (ms) and a status."""

    status: str
    safe_mask: np.ndarray
    footholds: list[Foothold]
    times_ms: dict[str, float] = field(default_factory=dict)
    resolution: float = 0.0
    origin_xy: np.ndarray = field(default_factory=lambda: np.zeros(2))
    inpainted: np.ndarray | None = None
    stats: dict[str, int] = field(default_factory=dict)   # acd_cuts, whittle_cuts, dropped
    #: per foothold, the RMS residual of its plane fit (m)
    plane_rms_m: list[float] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        """True when this frame was processed (even if no terrain is safe)."""
        return self.status in (STATUS_OK, STATUS_NO_SAFE)


class S3Pipeline:
    """Stateful S3: keeps the previous segmentation (and where the map was) for hysteresis."""

    def __init__(self, params: S3Params | None = None) -> None:
        self.params = params if params is not None else S3Params()
        check(self.params)
        p = self.params
        self.segmenter = Segmenter(p.k_hyst, p.k_safe, p.margin_kernel_px, p.clean_kernel_px,
                                   p.log_sigma_px, p.alpha_curve, p.inclination_kernel_px)
        self._prev_mask: np.ndarray | None = None
        self._prev_origin = np.zeros(2)
        self._prev_resolution = 0.0
        self._last_result: S3Result | None = None
        self._last_map_time: float | None = None
        self._labels: np.ndarray | None = None

    def reset(self) -> None:
        """Forget the previous segmentation (hysteresis starts afresh)."""
        self._prev_mask = None
        self._last_result = None
        self._last_map_time = None

    @property
    def previous(self) -> S3Result | None:
        """The last result that was processed ('ok' or 'no safe terrain')."""
        return self._last_result

    def _empty(self, status: str, shape: tuple[int, ...], resolution: float,
               origin: np.ndarray) -> S3Result:
        mask = np.zeros(shape if len(shape) == 2 else (0, 0), np.uint8)
        return S3Result(status, mask, [], {s: 0.0 for s in STAGES} | {"total": 0.0},
                        resolution, origin)

    def _keep_previous(self, status: str) -> S3Result:
        prev = self._last_result
        if prev is None:
            return self._empty(status, (0, 0), 0.0, np.zeros(2))
        return S3Result(status, prev.safe_mask, prev.footholds,
                        {s: 0.0 for s in STAGES} | {"total": 0.0}, prev.resolution,
                        prev.origin_xy, prev.inpainted, prev.stats, prev.plane_rms_m)

    def process(self, elevation: np.ndarray, resolution: float, origin_xy: np.ndarray,
                map_time_s: float | None = None, now_s: float | None = None,
                lowest: np.ndarray | None = None) -> S3Result:
        """Segment one elevation map (rows along y, NaN unknown; origin = centre of cell (0, 0))
        into convex footholds. Never raises on bad data: the status says what went wrong;
        a stale map returns the previous footholds, an empty or all-NaN map none. `lowest`
        is the map's optional layer of lowest points seen per cell, used by LNV inpainting.
        """
        p = self.params
        try:
            origin = np.asarray(origin_xy, dtype=np.float64).reshape(-1)
            e = np.asarray(elevation)
            resolution = float(resolution)
        except (TypeError, ValueError):
            return self._empty(f"{STATUS_BAD}: elevation, resolution or origin is not numeric",
                               (0, 0), 0.0, np.zeros(2))
        real = np.issubdtype(e.dtype, np.floating) or np.issubdtype(e.dtype, np.integer)
        if e.ndim != 2 or origin.size != 2 or not np.all(np.isfinite(origin)) or \
                not np.isfinite(resolution) or resolution <= 0.0 or not real:
            return self._empty(f"{STATUS_BAD}: need a 2D real map, finite origin (x, y) and "
                               "a positive resolution", e.shape,
                               resolution if np.isfinite(resolution) else 0.0, np.zeros(2))
        if e.size == 0:
            return self._empty(STATUS_EMPTY, e.shape, resolution, origin)
        if map_time_s is not None:
            if self._last_map_time is not None and map_time_s <= self._last_map_time:
                return self._keep_previous(STATUS_STALE)
            if now_s is not None and now_s - map_time_s > p.max_map_age_s:
                return self._keep_previous(STATUS_STALE)
        finite = np.isfinite(e)
        if not finite.any():
            return self._empty(STATUS_ALL_NAN, e.shape, resolution, origin)

        times: dict[str, float] = {}
        t0 = time.perf_counter()
        # IX-A-1: inpaint unknown cells (NS for continuous terrain, LNV for discrete)
        low = None
        if lowest is not None:
            low = np.asarray(lowest)
            if low.shape != e.shape or not np.issubdtype(low.dtype, np.floating):
                low = None                   # a malformed optional layer is ignored
        filled = inpaint(e, p.inpainting, p.inpaint_radius_px, lowest=low)
        t1 = time.perf_counter()
        # Eqs. (24)-(26) and their geometric mean
        score = self.segmenter.score(filled, resolution)
        t2 = time.perf_counter()
        # hysteresis on S_{k-1} (moved with the map), threshold, clean = open(close(erode))
        prev = None
        if self._prev_mask is not None and self._prev_mask.shape == e.shape and \
                abs(self._prev_resolution - resolution) <= 1e-9 * resolution:
            prev = shift_mask(self._prev_mask, self._prev_origin, origin, resolution)
        raw = self.segmenter.threshold(score, prev)
        mask = self.segmenter.clean(raw)
        t3 = time.perf_counter()
        stats: dict[str, int] = {}
        polys_px = convex_decomposition(
            mask, resolution, p.concavity_limit_m, p.min_polygon_area_m2,
            p.min_foothold_area_m2, p.contour_epsilon_px, p.whittle_tolerance_px,
            p.max_acd_cuts, p.max_footholds, p.cut_alpha_rad, p.cut_beta, p.cut_epsilon,
            p.cut_max_iters, p.max_whittle_cuts, stats)
        t4 = time.perf_counter()
        if self._labels is None or self._labels.shape != e.shape:
            self._labels = np.zeros(e.shape, np.int32)
        footholds: list[Foothold] = []
        plane_rms: list[float] = []
        normals, offsets, rms = fit_planes(filled, polys_px, resolution, origin, self._labels)
        for k, poly in enumerate(polys_px):  # one least-squares plane per polygon
            try:  # the decomposition's polygons are convex and counter-clockwise
                footholds.append(Foothold.from_ccw(origin + poly * resolution, normals[k],
                                                   float(offsets[k])))
            except ValueError:  # no area left in metres: not a foothold
                stats["dropped"] = stats.get("dropped", 0) + 1
                continue
            plane_rms.append(float(rms[k]))
        t5 = time.perf_counter()
        for name, (ta, tb) in zip(STAGES, ((t0, t1), (t1, t2), (t2, t3), (t3, t4), (t4, t5)),
                                  strict=True):
            times[name] = (tb - ta) * 1e3
        times["total"] = (t5 - t0) * 1e3

        self._prev_mask = mask
        self._prev_origin = origin.copy()
        self._prev_resolution = float(resolution)
        if map_time_s is not None:
            self._last_map_time = map_time_s
        status = STATUS_OK if footholds else STATUS_NO_SAFE
        stats["footholds"] = len(footholds)
        result = S3Result(status, mask, footholds, times, float(resolution), origin.copy(),
                          filled, stats, plane_rms)
        self._last_result = result
        return result
