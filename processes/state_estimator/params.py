"""The state estimator's settings: ``hw_config/gains/state_estimator.yaml`` as a dataclass.

``EstimatorParams`` has the file's shape (sections as nested dataclasses) and is read by
``runtime.params``: every key known, every value typed and in range, every error a
``ConfigError`` naming the file, the dotted key and what is allowed.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from runtime.params import spec

from .alip_filter import AlipFilterParams
from .contact import ContactParams
from .inekf import InEKFNoise, StillParams

DEFAULT_GAINS_FILE = Path(__file__).resolve().parents[2] / "hw_config" / "gains" / (
    "state_estimator.yaml"
)


@dataclass(frozen=True)
class PacketLimits:
    """Physically plausible ranges: a packet outside them is rejected, never passed on."""

    quat_norm_tol: float = spec(0.05, lo=0.0, lo_open=True)  # | |q| - 1 | of the IMU quaternion
    #: beyond the model's joint range (springs included)
    joint_margin_rad: float = spec(0.35, lo=0.0, lo_open=True, unit="rad")
    max_joint_vel: float = spec(100.0, lo=0.0, lo_open=True, unit="rad/s")
    max_gyro: float = spec(50.0, lo=0.0, lo_open=True, unit="rad/s")
    max_accel: float = spec(500.0, lo=0.0, lo_open=True, unit="m/s^2")  # impacts reach ~100
    max_torque: float = spec(500.0, lo=0.0, lo_open=True, unit="N m")  # joint side


@dataclass(frozen=True)
class InitPose:
    """Where the robot starts (world)."""

    xy_m: tuple[float, float] = spec((0.0, 0.0), unit="m")  # pelvis x, y at start-up
    ground_z_m: float = spec(0.0, unit="m")  # height of the ground under the feet at start-up


@dataclass(frozen=True)
class EstimatorParams:
    """Everything ``CassieEstimator`` and its process shell read from hw_config: the gains
    file, section by section (the process module's ``Gains``)."""

    inekf: InEKFNoise = spec(default_factory=InEKFNoise)
    still: StillParams = spec(default_factory=StillParams)
    contact: ContactParams = spec(default_factory=ContactParams)
    alip: AlipFilterParams = spec(default_factory=AlipFilterParams)
    limits: PacketLimits = spec(default_factory=PacketLimits)
    init: InitPose = spec(default_factory=InitPose)
    gravity: float = spec(9.81, lo=0.0, lo_open=True, unit="m/s^2")
    #: NETWORK_ copy of every n-th state (2 kHz / 10 = 200 Hz)
    network_every: int = spec(10, lo=1)
