"""Stable Steppability Segmentation (Section VI-A): inpainting, the curvature (24)-(25) and
inclination (26) safety criteria, their geometric mean, hysteresis and clean().

Every step is a whole-image OpenCV/numpy operation: no Python loop over cells. Images are
indexed [row, col] = [y, x], as in `lcmtypes/elevation_map_t`.
"""

from __future__ import annotations

import cv2
import numpy as np

# Eq. (24): mean of the 8 neighbours minus the centre pixel.
LAPLACIAN_KERNEL_24 = np.array([[1.0, 1.0, 1.0], [1.0, -8.0, 1.0], [1.0, 1.0, 1.0]]) / 8.0
# For a smooth image, kernel (24) returns (3/8) * (d2/dx2 + d2/dy2) in pixel units.
_KERNEL_24_TO_LAPLACIAN = 8.0 / 3.0


def inpaint(elevation: np.ndarray, method: str, radius_px: int = 3,
            lowest: np.ndarray | None = None) -> np.ndarray:
    """Fill NaN cells (Section IX-A-1).

    'ns': OpenCV's Navier-Stokes inpainting, matching value and gradient at the hole boundary
    (continuous terrain). 'lnv': least neighbouring value, the conservative choice for discrete
    terrain: every connected unknown region takes the lowest value on its rim, so an occluded
    gap is never raised to the stones around it. With the map's optional `lowest` layer (the
    lowest point seen in each cell: the visible depth of a gap's far wall) the rim values are
    those lowest points (our extension). Returns a float32 copy with no NaN; the input must
    hold at least one finite cell.
    """
    e = np.asarray(elevation, dtype=np.float32)
    missing = ~np.isfinite(e)
    if not missing.any():
        return e.copy()
    if method == "ns":
        src = e.copy()
        # NS needs the unknown region's frame; a constant fill keeps far-away cells sane
        src[missing] = np.float32(np.median(e[~missing]))
        return cv2.inpaint(src, missing.astype(np.uint8), radius_px, cv2.INPAINT_NS)
    if method == "lnv":
        seed = e
        if lowest is not None and lowest.shape == e.shape:
            low = np.asarray(lowest, dtype=np.float32)
            seed = np.fmin(e, np.where(np.isfinite(low), low, np.float32(np.inf)))
        count, labels = cv2.connectedComponents(missing.astype(np.uint8), connectivity=8)
        # the rim: known cells next to an unknown region, tagged with its label by dilation
        grown = cv2.dilate(labels.astype(np.float32), np.ones((3, 3), np.uint8))
        rim = ~missing & (grown > 0)
        rim_min = np.full(count, np.inf, dtype=np.float32)
        np.minimum.at(rim_min, grown[rim].astype(np.int64), seed[rim])
        rim_min[~np.isfinite(rim_min)] = np.min(seed[~missing])
        out = e.copy()
        out[missing] = rim_min[labels[missing]]
        return out
    raise ValueError(f"unknown inpainting method {method!r} (allowed: ns, lnv)")


def _pad_odd(image: np.ndarray, pad: int) -> np.ndarray:
    """Point-reflect the border (2 e0 - e_k): planes continue as planes, so the criteria see no
    false curvature or slope change at the map's edge. Same as np.pad(..., 'reflect', 'odd'),
    built from cv2.copyMakeBorder for speed."""
    if pad <= 0:
        return image.copy()
    if min(image.shape) <= pad:
        return np.pad(image, pad, mode="reflect", reflect_type="odd")
    out = cv2.copyMakeBorder(image, pad, pad, pad, pad, cv2.BORDER_REFLECT_101)
    h = pad
    out[:h] = 2.0 * out[h:h + 1] - out[:h]
    out[-h:] = 2.0 * out[-h - 1:-h] - out[-h:]
    out[:, :h] = 2.0 * out[:, h:h + 1] - out[:, :h]
    out[:, -h:] = 2.0 * out[:, -h - 1:-h] - out[:, -h:]
    return out


def curvature_criterion(elevation: np.ndarray, resolution: float, sigma_px: float,
                        alpha_c: float) -> np.ndarray:
    """Eq. (25): c_curve = min(1, exp(-alpha_c LoG(E))), penalising cells below an edge.

    LoG(E) is the Gaussian (sigma in px) followed by the Laplacian kernel (24), rescaled to the
    Laplacian in metres per px^2 and divided by the cell size; with alpha_c = 5 at 2.5 cm a step
    of about 6 cm makes the cell at its foot unsafe on its own (c_curve < 0.49).
    """
    radius = int(np.ceil(3.0 * sigma_px)) + 1
    e = np.asarray(elevation, dtype=np.float32)
    pad = radius + 1
    padded = _pad_odd(e - np.float32(e.mean()), pad)
    ksize = 2 * radius + 1
    smooth = cv2.GaussianBlur(padded, (ksize, ksize), sigma_px, borderType=cv2.BORDER_REPLICATE)
    # kernel (24) scaled so the result is alpha_c * LoG(E) / resolution
    kernel = (LAPLACIAN_KERNEL_24 * (-alpha_c * _KERNEL_24_TO_LAPLACIAN / resolution)
              ).astype(np.float32)
    neg = cv2.filter2D(smooth, -1, kernel, borderType=cv2.BORDER_REPLICATE)[pad:-pad, pad:-pad]
    # min(1, exp(-a x)) == exp(min(-a x, 0)): no bonus for negative curvature
    return np.exp(np.minimum(neg, 0.0, out=neg), out=neg)


def inclination_criterion(elevation: np.ndarray, resolution: float, kernel_px: int) -> np.ndarray:
    """Eq. (26): c_inc = n_z^2, n the smallest-eigenvalue eigenvector of the covariance of the
    cell positions in a k x k window (PCA normal [17]).

    On a regular grid var(x) = var(y) = s, cov(x, y) = 0, so the 3 x 3 covariance
    [[s, 0, p], [0, s, q], [p, q, r]] has a closed-form smallest eigenpair: with m = |(p, q)|,
    lambda = (s + r)/2 - sqrt(((r - s)/2)^2 + m^2) and n ~ (m, lambda - s) in the plane of
    (p, q) and z, hence n_z^2 = (lambda - s)^2 / (m^2 + (lambda - s)^2). No per-cell eigh.
    """
    k = int(kernel_px)
    half = k // 2
    e = np.asarray(elevation, dtype=np.float32)
    # centre the heights so float32 var(z) = E[z^2] - E[z]^2 does not cancel
    e = _pad_odd(e - np.float32(e.mean()), half)
    offs = (np.arange(k, dtype=np.float32) - half) * np.float32(resolution / (k * k))
    ones = np.ones(k, np.float32)
    border = cv2.BORDER_REPLICATE
    mean_z = cv2.blur(e, (k, k), borderType=border)
    mean_zz = cv2.blur(e * e, (k, k), borderType=border)
    # cov(x, z) = sum(dx z) / k^2 and cov(y, z), as separable ramp x box filters
    p = cv2.sepFilter2D(e, -1, offs, ones, borderType=border)
    q = cv2.sepFilter2D(e, -1, ones, offs, borderType=border)
    sl = (slice(half, -half), slice(half, -half)) if half > 0 else (slice(None), slice(None))
    r = mean_zz[sl] - np.square(mean_z[sl])                     # var(z)
    s = np.float32(resolution * resolution * (k * k - 1) / 12.0)  # var(x) = var(y)
    m2 = np.square(p[sl]) + np.square(q[sl])
    h = np.float32(0.5) * (r - s)
    delta = h - np.sqrt(h * h + m2)                             # lambda_min - s <= 0
    d2 = delta * delta
    den = m2 + d2
    # den == 0 only when m = 0 and r >= s: then the z axis is an eigenvector; call it flat
    return np.divide(d2, den, out=np.ones_like(den), where=den > 1e-30)


def shift_mask(prev: np.ndarray, prev_origin: np.ndarray, origin: np.ndarray,
               resolution: float) -> np.ndarray:
    """Re-index the previous segmentation onto the current (moved) grid; new cells are 0."""
    out = np.zeros_like(prev)
    d = np.round((np.asarray(origin) - np.asarray(prev_origin)) / resolution).astype(int)
    dc, dr = int(d[0]), int(d[1])
    rows, cols = prev.shape
    if abs(dr) >= rows or abs(dc) >= cols:
        return out
    out[max(-dr, 0):rows + min(-dr, 0), max(-dc, 0):cols + min(-dc, 0)] = \
        prev[max(dr, 0):rows + min(dr, 0), max(dc, 0):cols + min(dc, 0)]
    return out


class Segmenter:
    """S3 proper: S_k = clean([(prod c_i(E_k))^(1/M) + k_hyst S_{k-1}] > k_safe).

    Holds the structuring elements; the caller keeps S_{k-1} (it moves with the map).
    """

    def __init__(self, k_hyst: float, k_safe: float, margin_px: int, clean_px: int,
                 sigma_px: float, alpha_c: float, inclination_px: int) -> None:
        self.k_hyst = float(k_hyst)
        self.k_safe = float(k_safe)
        self.sigma_px = float(sigma_px)
        self.alpha_c = float(alpha_c)
        self.inclination_px = int(inclination_px)
        self.margin_kernel = (cv2.getStructuringElement(cv2.MORPH_ELLIPSE,
                                                        (margin_px, margin_px))
                              if margin_px > 1 else None)
        self.clean_kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (clean_px, clean_px))

    def score(self, inpainted: np.ndarray, resolution: float) -> np.ndarray:
        """Geometric mean of the M = 2 criteria, in [0, 1]."""
        c_curve = curvature_criterion(inpainted, resolution, self.sigma_px, self.alpha_c)
        c_inc = inclination_criterion(inpainted, resolution, self.inclination_px)
        return np.sqrt(c_curve * c_inc)

    def threshold(self, score: np.ndarray, previous: np.ndarray | None) -> np.ndarray:
        """The bracket of the S3 equation: score plus hysteresis on last frame's safe cells."""
        if previous is not None and self.k_hyst > 0.0:
            total = score + self.k_hyst * previous
        else:
            total = score
        return (total > self.k_safe).astype(np.uint8)

    def clean(self, raw: np.ndarray) -> np.ndarray:
        """clean(S) = open(close(erode(S))): the erosion is the safety margin for swing-foot
        error and foot length; close/open remove thin holes and protrusions."""
        s = raw
        if self.margin_kernel is not None:
            s = cv2.erode(s, self.margin_kernel)
        s = cv2.morphologyEx(s, cv2.MORPH_CLOSE, self.clean_kernel)
        return cv2.morphologyEx(s, cv2.MORPH_OPEN, self.clean_kernel)
