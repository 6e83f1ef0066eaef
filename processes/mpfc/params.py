"""MPFC parameters (Table V of the paper plus the physical constants it assumes): the MPFC
process's ``Gains``, read from hw_config/gains/mpfc.yaml by ``runtime.params.load(MpfcParams,
path, variant)`` (variant ``hardware`` or ``simulation``, the columns of Table V)."""

from __future__ import annotations

from dataclasses import dataclass

from runtime.errors import ConfigError
from runtime.params import spec

SEARCH_MODES = ("auto", "enumerate", "branch_and_bound")


@dataclass(frozen=True)
class MpfcParams:
    """Every MPFC parameter; names carry units. Table V references are in the YAML file; the
    defaults are its hardware column."""

    horizon_steps: int = spec(2, lo=1, hi=6)  # N
    t_ss_min_s: float = spec(0.27, lo=0.0, lo_open=True, unit="s")  # t_min
    t_ss_max_s: float = spec(0.33, lo=0.0, lo_open=True, unit="s")  # t_max
    com_height_m: float = spec(0.85, lo=0.0, lo_open=True, unit="m")  # H
    t_ss_s: float = spec(0.30, lo=0.0, lo_open=True, unit="s")  # T_ss
    t_ds_s: float = spec(0.10, lo=0.0, lo_open=True, unit="s")  # T_ds
    #: the first double stance, from standing (ours: processes.mpfc.gait.GaitClock)
    t_ds_start_s: float = spec(0.4, lo=0.0, hi=2.0, unit="s")
    w_time: float = spec(100.0, lo=0.0, unit="1/s^2")  # w_T
    step_width_m: float = spec(0.20, lo=0.0, unit="m")  # l
    w_ankle: float = spec(0.01, lo=0.0, unit="1/(N m)^2")  # w_u
    ankle_torque_max_nm: float = spec(22.0, lo=0.0, lo_open=True, unit="N m")  # u_max
    q_terminal: tuple[float, float, float, float] = spec(  # Q_N diagonal
        (100.0, 100.0, 1.0, 1.0), lo=0.0, lo_open=True)
    q_running: tuple[float, float, float, float] = spec(  # Q diagonal
        (0.001, 0.1, 0.01, 0.001), lo=0.0)
    r_step: tuple[float, float, float] = spec((25.0, 25.0, 0.0), lo=0.0)  # R diagonal
    com_pos_limit_m: tuple[float, float] = spec((0.35, 0.35), lo=0.0, lo_open=True, unit="m")
    com_vel_limit_mps: tuple[float, float] = spec((2.5, 1.5), lo=0.0, lo_open=True, unit="m/s")
    soft_constraint_cost: float = spec(1000.0, lo=0.0)
    mass_kg: float = spec(33.3, lo=0.0, lo_open=True, unit="kg")
    gravity_mps2: float = spec(9.81, lo=0.0, lo_open=True, unit="m/s^2")
    lateral_instant_transfer: bool = True  # Appendix A
    big_m_m: float = spec(10.0, lo=0.0, lo_open=True, unit="m")  # M of (20)
    crossover_margin_m: float = spec(0.06, lo=0.0, unit="m")  # ours: blade width + clearance
    trust_region_start_s: float = spec(0.27, lo=0.0, unit="s")
    trust_region_rate_mps: float = spec(1.0, lo=0.0, unit="m/s")
    foothold_max_count: int = spec(20, lo=1, hi=200)
    foothold_max_distance_m: float = spec(2.0, lo=0.0, lo_open=True, unit="m")
    foothold_anchor_m: float = spec(  # heights relative to the foothold under the stance foot
        0.05, lo=0.0, unit="m")
    min_normal_z: float = spec(0.2, lo=0.0, hi=1.0, lo_open=True)
    time_limit_ms: float = spec(30.0, lo=0.0, lo_open=True, unit="ms")
    search: str = spec("auto", choices=SEARCH_MODES)
    enumerate_max_leaves: int = spec(2000, lo=1)
    qp_eps_abs: float = spec(1e-9, lo=0.0, lo_open=True)
    qp_eps_rel: float = spec(1e-10, lo=0.0)
    optimality_rel_tol: float = spec(1e-8, lo=0.0, lo_open=True)

    def __post_init__(self) -> None:
        """The checks across fields (the ranges of single fields are ``spec``'s)."""
        if not 0.0 < self.t_ss_min_s <= self.t_ss_s <= self.t_ss_max_s:
            raise ConfigError("<MpfcParams>", "t_ss_min_s",
                              "need 0 < t_ss_min_s <= t_ss_s <= t_ss_max_s, got "
                              f"{self.t_ss_min_s} <= {self.t_ss_s} <= {self.t_ss_max_s}",
                              "0 < min <= nominal <= max")
        if not (self.r_step[0] > 0 and self.r_step[1] > 0 and self.r_step[2] == 0.0):
            raise ConfigError("<MpfcParams>", "r_step",
                              "x, y weights must be > 0 and the z weight 0 (footstep height is "
                              "set by the foothold plane, as in Table V)", "[>0, >0, 0]")

    @property
    def t_s2s_s(self) -> float:
        """Step-to-step period T_ss + T_ds."""
        return self.t_ss_s + self.t_ds_s
