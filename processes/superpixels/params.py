"""The superpixel segmenter's parameters (QuadPiPS, Asselmeier et al., Section V-D/E): read
from hw_config/gains/superpixels.yaml by ``runtime.params.load(SuperpixelParams, path)``.

The paper gives the health check's threshold (0.5) but no values for k_des, the weights
w_(.), the scales d_(.)^max or n_iter; the gains file says how each was chosen."""

from __future__ import annotations

from dataclasses import dataclass

from runtime.errors import ConfigError
from runtime.params import spec


@dataclass(frozen=True)
class SuperpixelParams:
    """Health check (eqs. (5)-(9)), steppability stand-in, SLIC (eqs. (10)-(14)), RANSAC and
    the convex regions (V-E)."""

    # --- health check, eqs. (5)-(9) and V-D-1 ---
    min_normal_z: float = spec(0.866, lo=0.0, hi=1.0)  # n . up must exceed this (paper: 0.5)
    normal_window_px: int = spec(3, lo=1, hi=15, unit="px")  # height box filter before (7)
    # --- the steppability label's stand-in (V-B: a learned model in the paper) ---
    max_step_m: float = spec(0.05, lo=0.0, lo_open=True, unit="m")  # 3 x 3 height span
    margin_px: int = spec(2, lo=0, hi=20, unit="px")  # erosion for the foot
    # --- SLIC, V-D-3 ---
    k_des: int = spec(49, lo=1, hi=10000)  # desired number of superpixels
    n_iter: int = spec(5, lo=1, hi=100)  # assignment + update iterations
    w_n: float = spec(1.0, lo=0.0)  # weight of d_n, eq. (11)
    w_p: float = spec(1.0, lo=0.0)  # weight of d_p, eq. (12)
    w_w: float = spec(1.0, lo=0.0)  # weight of d_w, eq. (13)
    w_c: float = spec(1.0, lo=0.0)  # weight of d_c, eq. (14)
    d_n_max: float = spec(0.1, lo=0.0, hi=2.0, lo_open=True)  # scale of 1 - n . n
    d_p_max_m: float = spec(0.03, lo=0.0, lo_open=True, unit="m")  # scale of the plane distance
    d_w_max_m: float = spec(0.36, lo=0.0, lo_open=True, unit="m")  # scale of the 3D distance
    d_c_max_px: float = spec(14.3, lo=0.0, lo_open=True, unit="px")  # scale of the px distance
    # --- RANSAC refinement of each cluster's normal ---
    ransac_hypotheses: int = spec(24, lo=1, hi=10000)
    ransac_threshold_m: float = spec(0.02, lo=0.0, lo_open=True, unit="m")
    seed: int = spec(0, lo=0)  # the RANSAC samples' seed: the same map, the same regions
    # --- convex planar regions, V-E ---
    min_area_m2: float = spec(0.02, lo=0.0, unit="m^2")  # smaller regions are dropped
    max_cuts: int = spec(16, lo=0, hi=1000)  # cuts clearing unsteppable cells from one hull

    def __post_init__(self) -> None:
        if self.normal_window_px % 2 == 0:  # a window centred on its cell
            raise ConfigError("<SuperpixelParams>", "normal_window_px",
                              f"must be odd, got {self.normal_window_px}", "1, 3, 5, ... px")
        if self.w_n + self.w_p + self.w_w + self.w_c <= 0.0:
            raise ConfigError("<SuperpixelParams>", "w_c", "all four weights are zero",
                              "at least one of w_n, w_p, w_w, w_c > 0")
