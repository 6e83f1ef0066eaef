"""S3 and convex-decomposition parameters (Table VIII): the S3 process's ``Gains``, read from
hw_config/gains/s3.yaml by ``runtime.params.load(S3Params, path, variant)``."""

from __future__ import annotations

from dataclasses import dataclass

from runtime.errors import ConfigError
from runtime.params import spec


@dataclass(frozen=True)
class S3Params:
    """Parameters of S3 (Section VI-A), ACD + whittling (VI-B, Alg. 1-2) and input checks."""

    # --- S3 (Table VIII) ---
    k_hyst: float = spec(0.4, lo=0.0, hi=1.0)                     # safety hysteresis
    k_safe: float = spec(0.7, lo=0.0, hi=1.0, lo_open=True)       # safety threshold
    margin_kernel_px: int = spec(4, lo=0, hi=31, unit="px")       # erode (safety margin)
    log_sigma_px: float = spec(2.0, lo=0.0, hi=20.0, lo_open=True, unit="px")
    alpha_curve: float = spec(5.0, lo=0.0, hi=1e4)                # alpha_c of Eq. (25)
    inclination_kernel_px: int = spec(5, lo=3, hi=31, unit="px")  # odd, Eq. (26)
    inpainting: str = spec("lnv", choices=("ns", "lnv"))          # Navier-Stokes / least neighbour
    inpaint_radius_px: int = spec(3, lo=1, hi=20, unit="px")
    clean_kernel_px: int = spec(3, lo=1, hi=15, unit="px")        # close/open of clean()
    # --- convex decomposition (Table VIII, Section VI-B) ---
    concavity_limit_m: float = spec(0.25, lo=0.0, hi=10.0, lo_open=True, unit="m")
    min_polygon_area_m2: float = spec(0.05, lo=0.0, hi=100.0, unit="m^2")
    min_foothold_area_m2: float = spec(0.02, lo=0.0, hi=100.0, unit="m^2")
    contour_epsilon_px: float = spec(0.5, lo=0.0, hi=5.0, unit="px")
    whittle_tolerance_px: float = spec(0.25, lo=0.0, hi=5.0, unit="px")
    max_acd_cuts: int = spec(24, lo=0, hi=10000)
    max_whittle_cuts: int = spec(64, lo=0, hi=100000)
    max_footholds: int = spec(32, lo=1, hi=1000)
    # --- MakeCut solver, Algorithm 2 ---
    cut_alpha_rad: float = spec(0.5, lo=0.0, hi=3.2, lo_open=True, unit="rad")
    cut_beta: float = spec(0.5, lo=0.0, hi=1.0, lo_open=True, hi_open=True)
    cut_epsilon: float = spec(1e-6, lo=0.0, hi=1.0, lo_open=True)
    cut_max_iters: int = spec(50, lo=1, hi=10000)
    # --- input checks ---
    max_map_age_s: float = spec(0.5, lo=0.0, hi=3600.0, lo_open=True, unit="s")

    def __post_init__(self) -> None:
        if self.inclination_kernel_px % 2 == 0:  # a window centred on its cell, Eq. (26)
            raise ConfigError("<S3Params>", "inclination_kernel_px",
                              f"must be odd, got {self.inclination_kernel_px}", "3, 5, 7, ... px")
