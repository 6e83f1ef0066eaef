"""Temporal-consistency metrics of Section VIII-D: frame-to-frame IoU of the safe terrain and
of the area covered by the convex decomposition, on the cells both maps hold."""

from __future__ import annotations

from collections.abc import Sequence

import cv2
import numpy as np

_SHIFT = 4


def coverage_mask(polygons_xy: Sequence[np.ndarray], shape: tuple[int, int],
                  resolution: float, origin_xy: np.ndarray) -> np.ndarray:
    """Cells (uint8) covered by any of the world-frame convex polygons (VIII-D-3 sampling)."""
    out = np.zeros(shape, np.uint8)
    scale = float(1 << _SHIFT)
    for poly in polygons_xy:  # one C call per polygon
        px = (np.asarray(poly) - np.asarray(origin_xy)) / resolution
        cv2.fillConvexPoly(out, np.rint(px * scale).astype(np.int32), 1, cv2.LINE_8, _SHIFT)
    return out


def overlap_views(shape: tuple[int, int], origin_a: np.ndarray, origin_b: np.ndarray,
                  resolution: float) -> tuple[tuple[slice, slice], tuple[slice, slice]]:
    """Index windows of grid a and grid b (same shape and resolution) over the cells they share
    (the robot-centred map moves in whole cells)."""
    d = np.round((np.asarray(origin_b) - np.asarray(origin_a)) / resolution).astype(int)
    dc, dr = int(d[0]), int(d[1])
    rows, cols = shape
    a = (slice(max(dr, 0), rows + min(dr, 0)), slice(max(dc, 0), cols + min(dc, 0)))
    b = (slice(max(-dr, 0), rows + min(-dr, 0)), slice(max(-dc, 0), cols + min(-dc, 0)))
    return a, b


def frame_iou(mask_a: np.ndarray, origin_a: np.ndarray, mask_b: np.ndarray,
              origin_b: np.ndarray, resolution: float) -> float:
    """IoU of the safe cells of two consecutive frames, restricted to the cells present in both
    frames (Section VIII-D-2); 1.0 when neither frame has a safe shared cell."""
    if mask_a.shape != mask_b.shape or mask_a.size == 0:
        return float("nan")
    va, vb = overlap_views(mask_a.shape, origin_a, origin_b, resolution)
    a = mask_a[va] > 0
    b = mask_b[vb] > 0
    union = np.count_nonzero(a | b)
    if union == 0:
        return 1.0
    return np.count_nonzero(a & b) / union
