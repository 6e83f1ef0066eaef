"""The state estimator's settings (``hw_config/gains/state_estimator.yaml``), validated.

Every bad value raises ``ConfigError`` naming the file, the dotted key and what is allowed.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from runtime.config import load_yaml
from runtime.errors import ConfigError

from .alip_filter import AlipFilterParams
from .contact import ContactParams
from .inekf import InEKFNoise, StillParams

DEFAULT_GAINS_FILE = Path(__file__).resolve().parents[2] / "hw_config" / "gains" / (
    "state_estimator.yaml"
)


@dataclass(frozen=True)
class PacketLimits:
    """Physically plausible ranges: a packet outside them is rejected, never passed on."""

    quat_norm_tol: float = 0.05  # | |q| - 1 | of the IMU quaternion
    joint_margin_rad: float = 0.35  # beyond the model's joint range (springs included)
    max_joint_vel: float = 100.0  # rad/s
    max_gyro: float = 50.0  # rad/s
    max_accel: float = 500.0  # m/s^2 (impacts reach ~100)
    max_torque: float = 500.0  # N m, joint side


@dataclass(frozen=True)
class EstimatorParams:
    """Everything ``CassieEstimator`` and its process shell read from hw_config."""

    inekf: InEKFNoise = field(default_factory=InEKFNoise)
    still: StillParams = field(default_factory=StillParams)
    contact: ContactParams = field(default_factory=ContactParams)
    alip: AlipFilterParams = field(default_factory=AlipFilterParams)
    limits: PacketLimits = field(default_factory=PacketLimits)
    init_xy: tuple[float, float] = (0.0, 0.0)  # pelvis x, y at start-up (world), m
    ground_z: float = 0.0  # height of the ground under the feet at start-up, m
    gravity: float = 9.81
    network_every: int = 10  # NETWORK_ copy of every n-th state (2 kHz / 10 = 200 Hz)
    source: str = "<defaults>"

    @classmethod
    def from_yaml(cls, path: str | Path) -> EstimatorParams:
        """Read and validate a gains file."""
        return cls.from_dict(load_yaml(Path(path)), str(path))

    @classmethod
    def from_dict(cls, doc: Any, file: str = "<dict>") -> EstimatorParams:
        """Validate a parsed gains mapping (``from_yaml`` without the file)."""
        r = _Reader(file)
        doc = r.mapping(doc, "<top level>")
        r.keys(doc, "", {"inekf", "still", "contact", "alip", "limits", "init", "gravity",
                         "network_every"})
        ine = r.mapping(doc.get("inekf", {}), "inekf")
        r.keys(ine, "inekf.", set(InEKFNoise.__dataclass_fields__))
        inekf = InEKFNoise(**{k: r.num(ine, "inekf", k, lo=0.0, lo_open=True) for k in ine})
        st = r.mapping(doc.get("still", {}), "still")
        r.keys(st, "still.", set(StillParams.__dataclass_fields__))
        still = StillParams(**{k: r.num(st, "still", k, lo=0.0, lo_open=True) for k in st})
        con = r.mapping(doc.get("contact", {}), "contact")
        r.keys(con, "contact.", set(ContactParams.__dataclass_fields__))
        contact = ContactParams(**{k: r.num(con, "contact", k, lo=0.0) for k in con})
        if contact.touchdown_speed_mps <= 0.0:
            raise ConfigError(file, "contact.touchdown_speed_mps",
                              f"{contact.touchdown_speed_mps} would never let a contact start",
                              allowed="> 0 m/s (about 1: a touchdown lands at ~0.3 m/s)")
        if contact.off_n >= contact.on_n:
            raise ConfigError(file, "contact.off_n", f"{contact.off_n} must be below "
                              f"contact.on_n ({contact.on_n}) for hysteresis")
        al = r.mapping(doc.get("alip", {}), "alip")
        r.keys(al, "alip.", set(AlipFilterParams.__dataclass_fields__))
        alip = AlipFilterParams(**{k: r.num(al, "alip", k, lo=0.0, lo_open=True) for k in al})
        lim = r.mapping(doc.get("limits", {}), "limits")
        r.keys(lim, "limits.", set(PacketLimits.__dataclass_fields__))
        limits = PacketLimits(**{k: r.num(lim, "limits", k, lo=0.0, lo_open=True) for k in lim})
        init = r.mapping(doc.get("init", {}), "init")
        r.keys(init, "init.", {"xy_m", "ground_z_m"})
        xy = init.get("xy_m", [0.0, 0.0])
        if (not isinstance(xy, list) or len(xy) != 2
                or not all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in xy)):
            raise ConfigError(file, "init.xy_m", f"must be [x, y] in metres, got {xy!r}")
        return cls(
            inekf=inekf, still=still, contact=contact, alip=alip, limits=limits,
            init_xy=(float(xy[0]), float(xy[1])),
            ground_z=float(r.num(init, "init", "ground_z_m", default=0.0)),
            gravity=float(r.num(doc, "", "gravity", default=9.81, lo=0.0, lo_open=True)),
            network_every=int(r.num(doc, "", "network_every", default=10, lo=1, integer=True)),
            source=file,
        )


class _Reader:
    """Typed accessors that raise ConfigError naming the file and key."""

    def __init__(self, file: str) -> None:
        self.file = file

    def mapping(self, v: Any, key: str) -> dict[str, Any]:
        if v is None:
            return {}
        if not isinstance(v, dict):
            raise ConfigError(self.file, key, f"must be a mapping, got {type(v).__name__}")
        return v

    def keys(self, d: dict[str, Any], prefix: str, allowed: set[str]) -> None:
        for k in d:
            if k not in allowed:
                raise ConfigError(self.file, f"{prefix}{k}", "unknown key",
                                  ", ".join(sorted(allowed)))

    def num(self, d: dict[str, Any], section: str, name: str, *, default: Any = ...,
            lo: float | None = None, hi: float | None = None, lo_open: bool = False,
            integer: bool = False) -> float:
        key = f"{section}.{name}" if section else name
        if name not in d:
            if default is ...:
                raise ConfigError(self.file, key, "is required")
            return default
        v = d[name]
        if isinstance(v, bool) or not isinstance(v, int if integer else (int, float)):
            raise ConfigError(self.file, key,
                              f"must be {'an integer' if integer else 'a number'}, got {v!r}")
        bad_lo = lo is not None and (v <= lo if lo_open else v < lo)
        if bad_lo or (hi is not None and v > hi) or v != v:
            rng = f"{'(' if lo_open else '['}{'-inf' if lo is None else lo}, "
            rng += f"{'inf' if hi is None else hi}]"
            raise ConfigError(self.file, key, f"{v!r} is out of range", allowed=rng)
        return v
