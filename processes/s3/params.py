"""S3 and convex-decomposition parameters (Table VIII), loaded from hw_config/gains/s3.yaml."""

from __future__ import annotations

import os
from dataclasses import dataclass

from processes.perception.config import bounded, load_params
from runtime.errors import ConfigError


@dataclass(frozen=True)
class S3Params:
    """Parameters of S3 (Section VI-A), ACD + whittling (VI-B, Alg. 1-2) and input checks."""

    # --- S3 (Table VIII) ---
    k_hyst: float = bounded(0.4, lo=0.0, hi=1.0)                 # safety hysteresis
    k_safe: float = bounded(0.7, lo=0.0, hi=1.0, lo_open=True)   # safety threshold
    margin_kernel_px: int = bounded(4, lo=0, hi=31, unit="px")   # erode (safety margin)
    log_sigma_px: float = bounded(2.0, lo=0.0, hi=20.0, lo_open=True, unit="px")
    alpha_curve: float = bounded(5.0, lo=0.0, hi=1e4)            # alpha_c of Eq. (25)
    inclination_kernel_px: int = bounded(5, lo=3, hi=31, unit="px")  # odd, Eq. (26)
    inpainting: str = bounded("lnv", choices=("ns", "lnv"))      # Navier-Stokes / least neighbour
    inpaint_radius_px: int = bounded(3, lo=1, hi=20, unit="px")
    clean_kernel_px: int = bounded(3, lo=1, hi=15, unit="px")    # close/open of clean()
    # --- convex decomposition (Table VIII, Section VI-B) ---
    concavity_limit_m: float = bounded(0.25, lo=0.0, hi=10.0, lo_open=True, unit="m")
    min_polygon_area_m2: float = bounded(0.05, lo=0.0, hi=100.0, unit="m^2")
    min_foothold_area_m2: float = bounded(0.02, lo=0.0, hi=100.0, unit="m^2")
    contour_epsilon_px: float = bounded(0.5, lo=0.0, hi=5.0, unit="px")
    whittle_tolerance_px: float = bounded(0.25, lo=0.0, hi=5.0, unit="px")
    max_acd_cuts: int = bounded(24, lo=0, hi=10000)
    max_whittle_cuts: int = bounded(64, lo=0, hi=100000)
    max_footholds: int = bounded(32, lo=1, hi=1000)
    # --- MakeCut solver, Algorithm 2 ---
    cut_alpha_rad: float = bounded(0.5, lo=0.0, hi=3.2, lo_open=True, unit="rad")
    cut_beta: float = bounded(0.5, lo=0.0, hi=1.0, lo_open=True, hi_open=True)
    cut_epsilon: float = bounded(1e-6, lo=0.0, hi=1.0, lo_open=True)
    cut_max_iters: int = bounded(50, lo=1, hi=10000)
    # --- input checks ---
    max_map_age_s: float = bounded(0.5, lo=0.0, hi=3600.0, lo_open=True, unit="s")

    @classmethod
    def from_yaml(cls, path: str | os.PathLike[str], profile: str | None = None) -> S3Params:
        """Load `profiles.<profile>` of `path`; raise ConfigError on a bad value."""
        params = load_params(cls, path, profile)
        if params.inclination_kernel_px % 2 == 0:
            raise ConfigError(str(path), "inclination_kernel_px", "must be odd",
                              "3, 5, 7, ... px")
        return params
