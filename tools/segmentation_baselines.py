"""The paper's plane-segmentation baselines (Section VIII-D, Table III), for the offline
perception benchmark (``cassie bench segmenters``): safe-terrain masks from an elevation map by
explicit plane segmentation, to compare with S3.

``EM_cupy``: the plane segmentation of elevation_mapping_cupy (its convex_plane_decomposition
package) with its default parameters (``PlaneSegParams``, from that package's
``parameters.yaml``): a median filter, a sliding-window plane fit per cell (RMS and
inclination), connected components of the planar cells, and for each component a global plane
fit that must hold every cell within a distance and a normal angle, else RANSAC refinement into
smaller planes. ``EM_cupy_NR`` ("no refinement"): the same components, each accepted or rejected
whole by the slope of its plane (< 30 deg). Both inpaint unknown cells with the least
neighbouring value (Table III). Written here from the paper's description and that package's
parameter list, in numpy and OpenCV; not a port of its C++ code.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from processes.s3.segmentation import inpaint


@dataclass(frozen=True)
class PlaneSegParams:
    """elevation_mapping_cupy's convex_plane_decomposition defaults (parameters.yaml)."""

    median_kernel_px: int = 3  # preprocessing.kernelSize
    kernel_px: int = 3  # sliding_window_plane_extractor.kernel_size
    patch_inclination_deg: float = 30.0  # plane_inclination_threshold_degrees
    cell_inclination_deg: float = 35.0  # local_plane_inclination_threshold_degrees
    patch_rms_m: float = 0.02  # plane_patch_error_threshold
    min_label_cells: int = 4  # min_number_points_per_label
    global_distance_m: float = 0.025  # global_plane_fit_distance_error_threshold
    global_angle_deg: float = 25.0  # global_plane_fit_angle_error_threshold_degrees
    ransac_epsilon_m: float = 0.025  # ransac_plane_refinement.epsilon
    ransac_normal_deg: float = 25.0  # ransac_plane_refinement.normal_threshold
    ransac_probability: float = 0.01  # ransac_plane_refinement.probability
    ransac_min_points: int = 4  # ransac_plane_refinement.min_points
    margin_px: int = 1  # contour_extraction.marginSize
    ransac_max_iters: int = 200  # (ours: a bound on the hypotheses per plane)


@dataclass
class PlaneSegResult:
    """A safe mask (uint8) and the planes found (per plane: its cells' count and slope)."""

    safe_mask: np.ndarray
    planes: int
    ransac_components: int  # components that failed the global fit and were refined


def _local_planes(z: np.ndarray, res: float, k: int) -> tuple[np.ndarray, np.ndarray]:
    """Per cell: the unit normal's z (cos of the inclination) and the RMS residual of the least
    squares plane through its k x k window (box filters: no loop over cells)."""
    offs = (np.arange(k) - k // 2) * res
    gx = np.tile(offs, (k, 1))  # x grows along columns
    gy = gx.T
    n = float(k * k)
    sxx = float((gx * gx).sum())
    # slopes of the window's plane (x and y offsets are zero-mean and orthogonal); filter2D
    # correlates, so these are sum(offset z) / sum(offset^2)
    a = cv2.filter2D(z, -1, (gx / sxx).astype(np.float32), borderType=cv2.BORDER_REPLICATE)
    b = cv2.filter2D(z, -1, (gy / sxx).astype(np.float32), borderType=cv2.BORDER_REPLICATE)
    mean = cv2.blur(z, (k, k), borderType=cv2.BORDER_REPLICATE)
    mean_sq = cv2.blur(z * z, (k, k), borderType=cv2.BORDER_REPLICATE)
    # residual variance = var(z) - the variance the plane explains, a^2 sxx/n + b^2 sxx/n
    var = np.maximum(mean_sq - mean * mean - (a * a + b * b) * (sxx / n), 0.0)
    cos_incl = 1.0 / np.sqrt(1.0 + a * a + b * b)
    return cos_incl, np.sqrt(var)


def _fit_plane(p: np.ndarray) -> tuple[np.ndarray, float]:
    """Least squares plane through points (m, 3): unit normal (z up) and offset d (n.p = d)."""
    c = p.mean(axis=0)
    _, _, vt = np.linalg.svd(p - c, full_matrices=False)
    n = vt[-1]
    if n[2] < 0.0:
        n = -n
    return n, float(n @ c)


def _ransac(p: np.ndarray, normals: np.ndarray, prm: PlaneSegParams,
            rng: np.random.Generator) -> list[np.ndarray]:
    """Planes found one after the other in points ``p`` (m, 3) with per-point ``normals``:
    each the hypothesis (three points) with the most inliers (distance below epsilon, normal
    within the threshold), refitted on them; stops when the rest is smaller than min_points.
    Returns the inlier index arrays."""
    cos_thr = math.cos(math.radians(prm.ransac_normal_deg))
    left = np.arange(len(p))
    found: list[np.ndarray] = []
    while len(left) >= max(prm.ransac_min_points, 3):
        q, nq = p[left], normals[left]
        best: np.ndarray | None = None
        # hypotheses for the wanted probability of missing the largest plane, as if it held
        # a tenth of the points (bounded)
        iters = min(prm.ransac_max_iters,
                    math.ceil(math.log(prm.ransac_probability) / math.log(1.0 - 0.1 ** 3)))
        idx = rng.integers(0, len(q), size=(iters, 3))
        for i, j, k in idx:
            n = np.cross(q[j] - q[i], q[k] - q[i])
            norm = float(np.linalg.norm(n))
            if norm < 1e-12:
                continue
            n = n / norm
            inl = np.flatnonzero((np.abs((q - q[i]) @ n) < prm.ransac_epsilon_m)
                                 & (np.abs(nq @ n) > cos_thr))
            if best is None or len(inl) > len(best):
                best = inl
        if best is None or len(best) < prm.ransac_min_points:
            break
        found.append(left[best])
        left = np.delete(left, best)
    return found


def segment(elevation: np.ndarray, resolution: float, refine: bool = True,
            prm: PlaneSegParams | None = None, seed: int = 0) -> PlaneSegResult:
    """A safe mask by plane segmentation: ``refine`` True is EM_cupy (RANSAC refinement of
    components that are not one plane), False is EM_cupy_NR (each component accepted or
    rejected by the slope of its plane). ``seed`` makes RANSAC repeatable."""
    prm = prm or PlaneSegParams()
    z = inpaint(np.asarray(elevation, dtype=np.float32), "lnv", 3)
    if not np.isfinite(z).any():
        return PlaneSegResult(np.zeros(z.shape, np.uint8), 0, 0)
    z = np.nan_to_num(z, nan=float(np.nanmin(z)))
    z = cv2.medianBlur(z.astype(np.float32), prm.median_kernel_px)
    cos_incl, rms = _local_planes(z, resolution, prm.kernel_px)
    planar = ((rms < prm.patch_rms_m)
              & (cos_incl > math.cos(math.radians(prm.patch_inclination_deg)))).astype(np.uint8)
    count, labels, stats, _ = cv2.connectedComponentsWithStats(planar, connectivity=4)
    rows, cols = z.shape
    jj, ii = np.meshgrid(np.arange(cols), np.arange(rows))
    pts_all = np.stack([jj * resolution, ii * resolution, z], axis=-1)
    # the cells' own normals, for the global fit's angle test and RANSAC
    gy, gx = np.gradient(z, resolution)
    nrm_all = np.stack([-gx, -gy, np.ones_like(z)], axis=-1)
    nrm_all /= np.linalg.norm(nrm_all, axis=-1, keepdims=True)
    safe = np.zeros(z.shape, np.uint8)
    cos_slope = math.cos(math.radians(prm.patch_inclination_deg))
    cos_glob = math.cos(math.radians(prm.global_angle_deg))
    rng = np.random.default_rng(seed)
    planes = refined = 0
    cell_ok = cos_incl > math.cos(math.radians(prm.cell_inclination_deg))
    for lab in range(1, count):
        if stats[lab, cv2.CC_STAT_AREA] < prm.min_label_cells:
            continue
        sel = labels == lab
        p, nr = pts_all[sel], nrm_all[sel]
        n, d = _fit_plane(p)
        if not refine:
            if n[2] > cos_slope:
                safe[sel] = 1
                planes += 1
            continue
        fits = (np.abs(p @ n - d).max() <= prm.global_distance_m
                and (nr @ n).min() >= cos_glob)
        if fits:
            if n[2] > cos_slope:
                safe[sel & cell_ok] = 1
                planes += 1
            continue
        refined += 1
        cells = np.flatnonzero(sel.ravel())
        for inl in _ransac(p, nr, prm, rng):
            n2, _ = _fit_plane(p[inl])
            if n2[2] > cos_slope:
                safe.ravel()[cells[inl]] = 1
                planes += 1
    if prm.margin_px > 0:  # the contour's boundary offset
        kernel = np.ones((2 * prm.margin_px + 1,) * 2, np.uint8)
        safe = cv2.erode(safe, kernel)
    return PlaneSegResult(safe, planes, refined)
