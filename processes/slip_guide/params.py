"""The SLIP guide planner's parameters (Bartlett & Manchester, Sections II-IV), for Cassie
where its body differs from the paper's robot; loaded from hw_config/gains/slip_guide.yaml by
``runtime.params.load``. The paper gives no weights ("tuned"), so every weight is ours."""

from __future__ import annotations

from dataclasses import dataclass

from runtime.errors import ConfigError
from runtime.params import spec


@dataclass(frozen=True)
class SlipParams:
    """Problem 2 and Algorithm 1 of Bartlett & Manchester, plus the candidate sampling. Units
    in the names; weights are dimensionless multipliers of terms in SI units."""

    # -- time (Table I) ----------------------------------------------------------------
    dt_s: float = spec(0.15, lo=0.01, hi=1.0, unit="s")  # t of (1), the sample time
    horizon_s: float = spec(1.5, lo=0.1, hi=20.0, unit="s")  # T = N t
    # -- the robot (ours: Cassie's, not the paper's 1 m SLIP) -------------------------------
    com_height_m: float = spec(0.85, lo=0.3, hi=2.0, unit="m")  # nominal CoM above ground
    mass_kg: float = spec(33.3, lo=0.0, lo_open=True, unit="kg")  # converts a_max to force
    gravity_mps2: float = spec(9.81, lo=0.0, lo_open=True, unit="m/s^2")  # g of (1)
    reach_m: float = spec(1.0, lo=0.1, hi=3.0, unit="m")  # R of the RKNN search (II-A)
    leg_force_max_n: float = spec(820.0, lo=0.0, lo_open=True, unit="N")  # a_max * m
    friction_mu: float = spec(0.6, lo=0.0, lo_open=True, hi=5.0)  # mu of (3)
    # -- candidates (II-A) ------------------------------------------------------------------
    knn_k: int = spec(20, lo=1, hi=200)  # K, candidates per time step (Table I: 10, 20)
    candidate_spacing_m: float = spec(0.08, lo=0.005, hi=1.0, unit="m")  # foothold grid
    cost_unsafe: float = spec(4.0, lo=0.0)  # C = 1 + cost_unsafe (1 - S3 score)
    # -- path (Problem 2) -------------------------------------------------------------------
    path_tol_m: float = spec(0.1, lo=0.0, lo_open=True, unit="m")  # |s - s*| <= tol
    # -- weights of (10)-(12), Problem 2 ------------------------------------------------------
    w_env: float = spec(1.0, lo=0.0)  # w_0 of (15), on C o alpha (alpha in 1/s^2)
    w_tc: float = spec(2e-3, lo=0.0)  # w_1 of (8), on |d alpha / dt|^2
    w_path: float = spec(1000.0, lo=0.0)  # w_2 of (7), on |s - s*|^2 (m^2)
    w_vel: float = spec(0.5, lo=0.0)  # w of (7), on |ds/dt - ds*/dt|^2 (relative to w_2)
    w_jerk: float = spec(2e-3, lo=0.0)  # w_3 of (9), on |j|^2 ((m/s^3)^2)
    w_rw: float = spec(1.0, lo=0.0)  # w_4 of (16), the reweighting term
    # -- reweighting (14)-(16), Algorithm 1 -------------------------------------------------
    rw_eps: float = spec(0.3, lo=0.0, lo_open=True, unit="1/s^2")  # epsilon of (16)
    card_bound: float = spec(2.9, lo=0.0, lo_open=True)  # the bound on (16) (Problem 2)
    card_slack_weight: float = spec(1e3, lo=0.0, lo_open=True)  # exact penalty (ours)
    rw_iterations: int = spec(4, lo=0, hi=50)  # n_rw of Algorithm 1 (Section IV-A: 4)
    card_tol_mps2: float = spec(0.5, lo=0.0, unit="m/s^2")  # a contact counts in (5) above
    # -- phase/side assignment (III-E) ------------------------------------------------------
    merge_radius_m: float = spec(0.09, lo=0.0, unit="m")  # same foothold across time steps
    # -- solver -----------------------------------------------------------------------------
    qp_eps_abs: float = spec(1e-6, lo=0.0, lo_open=True)
    qp_eps_rel: float = spec(1e-7, lo=0.0, lo_open=True)
    qp_max_iter: int = spec(200, lo=1)

    def __post_init__(self) -> None:
        """The checks across fields: a horizon of whole samples, a reach below the hip."""
        if self.steps < 2:
            raise ConfigError("<SlipParams>", "horizon_s",
                              f"{self.horizon_s} s holds fewer than two samples of "
                              f"{self.dt_s} s", f">= {2 * self.dt_s} s")
        if self.reach_m <= self.com_height_m * 0.9:
            raise ConfigError("<SlipParams>", "reach_m",
                              f"{self.reach_m} m barely reaches the ground from "
                              f"com_height_m {self.com_height_m} m",
                              f"> {0.9 * self.com_height_m:.3g} m")

    @property
    def steps(self) -> int:
        """N, samples of the horizon (T / t, rounded: 1.5 / 0.15 = 10)."""
        return round(self.horizon_s / self.dt_s)

    @property
    def a_max_mps2(self) -> float:
        """a_max of Problem 2: one leg's largest acceleration of the CoM."""
        return self.leg_force_max_n / self.mass_kg

    @property
    def gravity(self) -> tuple[float, float, float]:
        """g of (1) as a vector (world z up)."""
        return (0.0, 0.0, -self.gravity_mps2)
