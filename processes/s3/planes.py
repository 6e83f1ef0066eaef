"""Least-squares plane per convex polygon (Section VI-B, last paragraph).

The paper fits the plane to the polygon's vertices projected on the map; we fit to every
(inpainted) map cell the polygon covers: more samples, the same estimator, and no single edge
cell can tilt the plane.
"""

from __future__ import annotations

import cv2
import numpy as np

_SHIFT = 4
_SUBPIXEL = float(1 << _SHIFT)
_STRIDE = 2


def bilinear(image: np.ndarray, xy_px: np.ndarray) -> np.ndarray:
    """Bilinear lookup of image at pixel coordinates (x = column, y = row), clamped."""
    x = np.clip(xy_px[:, 0], 0.0, image.shape[1] - 1.0)
    y = np.clip(xy_px[:, 1], 0.0, image.shape[0] - 1.0)
    x0 = np.minimum(np.floor(x).astype(int), image.shape[1] - 2) if image.shape[1] > 1 else \
        np.zeros(len(x), int)
    y0 = np.minimum(np.floor(y).astype(int), image.shape[0] - 2) if image.shape[0] > 1 else \
        np.zeros(len(y), int)
    x1 = np.minimum(x0 + 1, image.shape[1] - 1)
    y1 = np.minimum(y0 + 1, image.shape[0] - 1)
    fx, fy = x - x0, y - y0
    top = image[y0, x0] * (1 - fx) + image[y0, x1] * fx
    bot = image[y1, x0] * (1 - fx) + image[y1, x1] * fx
    return top * (1 - fy) + bot * fy


def fit_planes(elevation: np.ndarray, polys_px: list[np.ndarray], resolution: float,
               origin_xy: np.ndarray, labels: np.ndarray | None = None
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Least-squares planes z = a x + b y + c, one per convex polygon, all at once.

    The polygons (pixel coordinates, disjoint) are rasterised into one label image, and the
    sums of the normal equations come from np.bincount per label over every other cell in each
    direction: no loop over cells. A polygon with fewer than 3 such cells is fitted to its
    vertices (bilinear map heights) instead.
    Returns unit normals (P, 3) with n_z > 0, offsets d (P,) with n . p = d, RMS residuals (P,).
    """
    count = len(polys_px)
    normals = np.tile(np.array([0.0, 0.0, 1.0]), (count, 1))
    offsets = np.zeros(count)
    rms = np.zeros(count)
    if count == 0:
        return normals, offsets, rms
    if labels is None or labels.shape != elevation.shape:
        labels = np.zeros(elevation.shape, np.int32)
    else:
        labels.fill(0)
    for k, poly in enumerate(polys_px):   # one C call per polygon
        pts = np.rint(poly * _SUBPIXEL).astype(np.int32)
        cv2.fillConvexPoly(labels, pts, k + 1, lineType=cv2.LINE_8, shift=_SHIFT)
    # every other cell in each direction: a quarter of the work, thousands of samples left
    sub = labels[::_STRIDE, ::_STRIDE]
    rows, cols = np.nonzero(sub)
    lab = sub[rows, cols] - 1
    rows, cols = rows * _STRIDE, cols * _STRIDE
    z = elevation[rows, cols].astype(np.float64)
    ok = np.isfinite(z)
    lab, z = lab[ok], z[ok]
    # metres from the map's cell (0, 0); added back to the offset below
    x = cols[ok] * resolution
    y = rows[ok] * resolution
    n = np.bincount(lab, minlength=count).astype(np.float64)
    sums = [np.bincount(lab, weights=v, minlength=count)
            for v in (x, y, z, x * x, y * y, x * y, x * z, y * z, z * z)]
    sx, sy, sz, sxx, syy, sxy, sxz, syz, szz = sums
    nn = np.maximum(n, 1.0)
    mx, my, mz = sx / nn, sy / nn, sz / nn
    cxx = sxx - nn * mx * mx + 1e-12
    cyy = syy - nn * my * my + 1e-12
    cxy = sxy - nn * mx * my
    cxz = sxz - nn * mx * mz
    cyz = syz - nn * my * mz
    czz = np.maximum(szz - nn * mz * mz, 0.0)
    det = cxx * cyy - cxy * cxy
    good = (n >= 3) & (det > 1e-18)
    safe_det = np.where(good, det, 1.0)
    a = np.where(good, (cyy * cxz - cxy * cyz) / safe_det, 0.0)
    b = np.where(good, (cxx * cyz - cxy * cxz) / safe_det, 0.0)
    # residual sum of squares of the centred fit
    rss = np.maximum(czz - a * cxz - b * cyz, 0.0)
    rms = np.sqrt(rss / nn)
    for k in np.flatnonzero(n < 3):       # tiny polygons: fall back to the vertices
        zv = bilinear(elevation, polys_px[k])
        zv = zv[np.isfinite(zv)]
        mx[k] = float(polys_px[k][:, 0].mean()) * resolution
        my[k] = float(polys_px[k][:, 1].mean()) * resolution
        mz[k] = float(zv.mean()) if zv.size else 0.0
    norm = np.sqrt(1.0 + a * a + b * b)
    normals = np.column_stack((-a / norm, -b / norm, 1.0 / norm))
    px = mx + origin_xy[0]
    py = my + origin_xy[1]
    offsets = normals[:, 0] * px + normals[:, 1] * py + normals[:, 2] * mz
    return normals, offsets, rms
