"""The DCM planner's parameters (Xiang et al., Table I), retuned for Cassie where its legs
differ from Digit's; loaded from hw_config/gains/dcm_planner.yaml by ``runtime.params.load``."""

from __future__ import annotations

import math
from dataclasses import dataclass

from runtime.errors import ConfigError
from runtime.params import spec

#: the ablations of the paper's Section IV: (A) the planner, (B) a fixed step duration,
#: (C) a two-step preview, (D) no viability constraints (15)-(17)
VARIANTS = ("A", "B", "C", "D")


@dataclass(frozen=True)
class DcmParams:
    """Table I of Xiang et al. and the weights of its cost (14), which the paper leaves out
    ("tuned empirically"). Units in the names."""

    horizon_steps: int = spec(4, lo=2, hi=6)  # N: steps previewed, the current one included
    t_nom_s: float = spec(0.4, lo=0.1, hi=2.0, unit="s")  # nominal step duration
    t_min_s: float = spec(0.35, lo=0.05, hi=2.0, unit="s")  # shortest first step
    t_max_s: float = spec(0.55, lo=0.05, hi=2.0, unit="s")  # longest first step
    #: the gait's double stance, part of every step (Cassie's, the MPFC's T_ds): where the
    #: liftoff falls in the template's step (processes/dcm_planner/solver.py)
    t_ds_s: float = spec(0.1, lo=0.0, hi=1.0, unit="s")
    l_min_m: float = spec(-0.6, lo=-2.0, hi=2.0, unit="m")  # stride length bounds (19)
    l_max_m: float = spec(0.6, lo=0.01, hi=2.0, unit="m")
    w_min_m: float = spec(0.08, lo=0.0, hi=2.0, unit="m")  # stride width bounds (19)
    w_max_m: float = spec(0.45, lo=0.01, hi=2.0, unit="m")
    #: (16'), ours: walking forward, the DCM at a step's start no more than this behind its
    #: stance foot (inf: off, the paper's symmetric (16) only); module problem.py
    dcm_behind_max_m: float = spec(math.inf, lo=0.0, unit="m")
    delta_x_m: float = spec(0.04, lo=0.0, hi=1.0, unit="m")  # robustness margins of (16), (15)
    delta_y_m: float = spec(0.04, lo=0.0, hi=1.0, unit="m")
    com_height_m: float = spec(0.85, lo=0.3, hi=2.0, unit="m")  # z_c of lambda = sqrt(g / z_c)
    gravity_mps2: float = spec(9.81, lo=0.0, lo_open=True, unit="m/s^2")
    nominal_width_m: float = spec(0.15, lo=0.0, hi=1.0, unit="m")  # p_nom^y of (14)
    w_goal: float = spec(1.0, lo=0.0, unit="1/m^2")  # w_z of (14), every stage
    w_sigma: float = spec(1.0, lo=0.0)  # w_sigma of (14)
    w_stride_x: float = spec(10.0, lo=0.0, unit="1/m^2")  # w_x of (14)
    w_stride_y: float = spec(10.0, lo=0.0, unit="1/m^2")  # w_y of (14)
    variant: str = spec("A", choices=VARIANTS)  # the paper's ablation (A: the planner)
    # search and footholds, as the MPFC's
    foothold_max_count: int = spec(20, lo=1, hi=200)
    foothold_max_distance_m: float = spec(2.5, lo=0.1, unit="m")
    foothold_anchor_m: float = spec(0.05, lo=0.0, unit="m")
    min_normal_z: float = spec(0.2, lo=0.0, hi=1.0)
    big_m_m: float = spec(10.0, lo=0.0, lo_open=True, unit="m")  # M_big of (18) (Gurobi's)
    time_limit_ms: float = spec(30.0, lo=0.0, lo_open=True, unit="ms")
    search: str = spec("auto", choices=("auto", "enumerate", "branch_and_bound"))
    enumerate_max_leaves: int = spec(2000, lo=1)
    qp_eps_abs: float = spec(1e-9, lo=0.0, lo_open=True)
    qp_eps_rel: float = spec(1e-10, lo=0.0, lo_open=True)
    optimality_rel_tol: float = spec(1e-8, lo=0.0)

    def __post_init__(self) -> None:
        """The checks across fields."""
        if not self.t_min_s <= self.t_nom_s <= self.t_max_s:
            raise ConfigError("<DcmParams>", "t_nom_s",
                              f"{self.t_nom_s} is outside [t_min_s, t_max_s]",
                              f"[{self.t_min_s}, {self.t_max_s}] s")
        if self.l_min_m >= self.l_max_m or self.w_min_m >= self.w_max_m:
            raise ConfigError("<DcmParams>", "l_min_m",
                              "the stride bounds must have min < max", "l_min < l_max, "
                              "w_min < w_max")

    @property
    def lam(self) -> float:
        """lambda = sqrt(g / z_c), the template's natural frequency (1/s)."""
        return math.sqrt(self.gravity_mps2 / self.com_height_m)

    @property
    def steps(self) -> int:
        """N of the preview (the variant C's is 2)."""
        return 2 if self.variant == "C" else self.horizon_steps

    @property
    def fixed_timing(self) -> bool:
        """The variant B: sigma_1 held at its nominal (20) like the later steps."""
        return self.variant == "B"

    @property
    def viability(self) -> bool:
        """Constraints (15)-(17) on (all variants but D)."""
        return self.variant != "D"
