"""MPFC parameters (Table V of the paper plus the physical constants it assumes), from YAML."""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any

import yaml

from runtime.config import safe_load
from runtime.errors import ConfigError

DEFAULT_YAML = Path(__file__).resolve().parents[2] / "hw_config" / "gains" / "mpfc.yaml"
SEARCH_MODES = ("auto", "enumerate", "branch_and_bound")


@dataclass(frozen=True)
class MpfcParams:
    """Every MPFC parameter; names carry units. Table V references are in the YAML file."""

    horizon_steps: int = 2  # N
    t_ss_min_s: float = 0.27  # t_min
    t_ss_max_s: float = 0.33  # t_max
    com_height_m: float = 0.85  # H
    t_ss_s: float = 0.30  # T_ss
    t_ds_s: float = 0.10  # T_ds
    w_time: float = 100.0  # w_T
    step_width_m: float = 0.20  # l
    w_ankle: float = 0.01  # w_u
    ankle_torque_max_nm: float = 22.0  # u_max
    q_terminal: tuple[float, float, float, float] = (100.0, 100.0, 1.0, 1.0)  # Q_N diagonal
    q_running: tuple[float, float, float, float] = (0.001, 0.1, 0.01, 0.001)  # Q diagonal
    r_step: tuple[float, float, float] = (25.0, 25.0, 0.0)  # R diagonal
    com_pos_limit_m: tuple[float, float] = (0.35, 0.35)
    com_vel_limit_mps: tuple[float, float] = (2.5, 1.5)
    soft_constraint_cost: float = 1000.0
    mass_kg: float = 33.3
    gravity_mps2: float = 9.81
    lateral_instant_transfer: bool = True  # Appendix A
    big_m_m: float = 10.0  # M of (20)
    crossover_margin_m: float = 0.0
    trust_region_start_s: float = 0.27
    trust_region_rate_mps: float = 1.0
    foothold_max_count: int = 20
    foothold_max_distance_m: float = 2.0
    foothold_anchor_m: float = 0.05  # heights relative to the foothold under the stance foot
    min_normal_z: float = 0.2
    time_limit_ms: float = 30.0
    search: str = "auto"
    enumerate_max_leaves: int = 2000
    qp_eps_abs: float = 1e-9
    qp_eps_rel: float = 1e-10
    optimality_rel_tol: float = 1e-8

    @property
    def t_s2s_s(self) -> float:
        """Step-to-step period T_ss + T_ds."""
        return self.t_ss_s + self.t_ds_s

    @classmethod
    def from_yaml(cls, path: str | Path = DEFAULT_YAML, variant: str = "hardware") -> MpfcParams:
        """Load `variant` ('hardware' or 'simulation', the columns of Table V) from `path`.

        Raises ConfigError naming the file and key on a missing, unknown or invalid value.
        """
        path = Path(path)
        try:
            raw = safe_load(path.read_text(encoding="utf-8"))
        except OSError as exc:
            raise ConfigError(str(path), "<file>", f"cannot read: {exc}") from exc
        except yaml.YAMLError as exc:
            raise ConfigError(str(path), "<file>", f"not valid YAML: {exc}") from exc
        if not isinstance(raw, dict) or variant not in raw:
            raise ConfigError(
                str(path), variant, "missing parameter set", "hardware, simulation"
            )
        section = raw[variant]
        if not isinstance(section, dict):
            raise ConfigError(str(path), variant, "must be a mapping of parameters")
        return cls.from_mapping(section, str(path), variant)

    @classmethod
    def from_mapping(
        cls, data: dict[str, Any], file: str = "<dict>", prefix: str = ""
    ) -> MpfcParams:
        """Build and validate from a flat mapping (every field required, no unknown keys)."""
        names = {f.name: f for f in fields(cls)}
        def key(k: str) -> str:
            return f"{prefix}.{k}" if prefix else k

        for k in data:
            if k not in names:
                raise ConfigError(file, key(k), "unknown parameter", ", ".join(sorted(names)))
        values: dict[str, Any] = {}
        for name, f in names.items():
            if name not in data:
                raise ConfigError(file, key(name), "missing")
            values[name] = _coerce(file, key(name), data[name], f.default)
        params = cls(**values)
        params.validate(file, prefix)
        return params

    def validate(self, file: str = "<params>", prefix: str = "") -> None:
        """Check ranges and relations between parameters; raise ConfigError on the first bad one."""
        def key(k: str) -> str:
            return f"{prefix}.{k}" if prefix else k

        def need(ok: bool, name: str, problem: str, allowed: str) -> None:
            if not ok:
                raise ConfigError(file, key(name), problem, allowed)

        need(1 <= self.horizon_steps <= 6, "horizon_steps", "out of range", "1..6")
        for name in ("com_height_m", "t_ss_s", "t_ds_s", "mass_kg", "gravity_mps2", "big_m_m",
                     "ankle_torque_max_nm", "foothold_max_distance_m", "time_limit_ms",
                     "qp_eps_abs", "optimality_rel_tol"):
            need(getattr(self, name) > 0.0, name, f"must be > 0, got {getattr(self, name)}", "> 0")
        for name in ("w_time", "w_ankle", "soft_constraint_cost", "step_width_m",
                     "foothold_anchor_m",
                     "crossover_margin_m", "trust_region_start_s", "trust_region_rate_mps",
                     "qp_eps_rel"):
            need(getattr(self, name) >= 0.0, name, f"must be >= 0, got {getattr(self, name)}",
                 ">= 0")
        need(0.0 < self.t_ss_min_s <= self.t_ss_s <= self.t_ss_max_s, "t_ss_min_s",
             "need 0 < t_ss_min_s <= t_ss_s <= t_ss_max_s", "0 < min <= nominal <= max")
        need(all(v > 0 for v in self.q_terminal), "q_terminal", "diagonal must be > 0", "> 0")
        need(all(v >= 0 for v in self.q_running), "q_running", "diagonal must be >= 0", ">= 0")
        need(self.r_step[0] > 0 and self.r_step[1] > 0 and self.r_step[2] == 0.0, "r_step",
             "x, y weights must be > 0 and the z weight 0 (footstep height is set by the "
             "foothold plane, as in Table V)", "[>0, >0, 0]")
        need(all(v > 0 for v in self.com_pos_limit_m), "com_pos_limit_m", "must be > 0", "> 0")
        need(all(v > 0 for v in self.com_vel_limit_mps), "com_vel_limit_mps", "must be > 0", "> 0")
        need(1 <= self.foothold_max_count <= 200, "foothold_max_count", "out of range", "1..200")
        need(0.0 < self.min_normal_z <= 1.0, "min_normal_z", "out of range", "(0, 1]")
        need(self.search in SEARCH_MODES, "search", f"unknown mode {self.search!r}",
             ", ".join(SEARCH_MODES))
        need(self.enumerate_max_leaves >= 1, "enumerate_max_leaves", "must be >= 1", ">= 1")


def _coerce(file: str, key: str, value: Any, default: Any) -> Any:
    """Convert a YAML value to the type of the field's default, or raise ConfigError."""
    if isinstance(default, bool):
        if not isinstance(value, bool):
            raise ConfigError(file, key, f"expected true/false, got {value!r}", "true, false")
        return value
    if isinstance(default, int):
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(file, key, f"expected an integer, got {value!r}", "integer")
        return value
    if isinstance(default, float):
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(
            value
        ):
            raise ConfigError(file, key, f"expected a finite number, got {value!r}", "number")
        return float(value)
    if isinstance(default, str):
        if not isinstance(value, str):
            raise ConfigError(file, key, f"expected a string, got {value!r}", "string")
        return value
    if isinstance(default, tuple):
        if not isinstance(value, list) or len(value) != len(default):
            raise ConfigError(
                file, key, f"expected a list of {len(default)} numbers, got {value!r}",
                f"[{', '.join(['number'] * len(default))}]",
            )
        out = []
        for v in value:
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise ConfigError(file, key, f"expected finite numbers, got {value!r}", "numbers")
            out.append(float(v))
        return tuple(out)
    raise ConfigError(file, key, "unsupported parameter type")  # pragma: no cover
