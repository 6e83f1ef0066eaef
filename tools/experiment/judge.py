"""The judge of a walking trial: its figures (``Trial``) and how they are judged from the sim's
ground truth (falls, distance, speed against the command, footsteps outside every foothold)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

FALL_HEIGHT_M = 0.6
MIN_SWING_S = 0.1  # shorter airborne spells are contact flicker, not steps
HEADING_GAIN = 1.0  # operator's yaw rate per radian of heading error (Section VIII-A)
SPEED_TOLERANCE = 0.15


@dataclass
class Trial:
    """Figures of one trial; names carry their unit."""

    experiment: str
    seed: int
    duration_s: float = 0.0
    distance_m: float = 0.0
    mean_velocity_mps: float = 0.0
    commanded_velocity_mps: float = 0.0
    velocity_error_ratio: float = 0.0
    fell: bool = False
    fall_time_s: float = -1.0
    min_pelvis_height_m: float = 0.0
    footsteps: int = 0
    footsteps_outside: int = 0
    success: bool = False
    wall_s: float = 0.0
    mode: str = "harness"  # harness (deterministic, one process), lockstep or realtime (launch)
    timing: dict[str, dict[str, Any]] = field(default_factory=dict)  # live runs: report's loops
    cpu: dict[str, Any] = field(default_factory=dict)  # live runs: the report's CPU table
    realtime: dict[str, Any] = field(default_factory=dict)  # live runs: real-time checks
    notes: list[str] = field(default_factory=list)



class Judge:
    """Watches GROUND_TRUTH: falls, distance, speed and where each foot touches down."""

    def __init__(self, footholds: list[Any], walk_start_s: float,
                 ground: Callable[[float, float], float] | None = None) -> None:
        self.footholds = footholds
        self.walk_start_s = walk_start_s
        #: height of the terrain under (x, y): a fall is the pelvis below FALL_HEIGHT_M over
        #: it (on stairs a robot lying on the landing has its pelvis above 0.6 m)
        self.ground = ground if ground is not None else (lambda x, y: 0.0)
        self.x0: float | None = None
        self.x_last = 0.0
        self.t_last = 0.0
        self.min_z = np.inf
        self.fall_t: float | None = None
        self.prev_contact = [True, True]
        self.lift_t = [-1.0, -1.0]  # when each foot last left the ground
        self.touchdowns: list[tuple[float, np.ndarray]] = []

    def __call__(self, t_us: int, gt: Any) -> None:
        t = gt.header.utime * 1e-6
        z = gt.q[2] - self.ground(gt.q[0], gt.q[1])
        self.min_z = min(self.min_z, z)
        if z < FALL_HEIGHT_M and self.fall_t is None:
            self.fall_t = t
        if t >= self.walk_start_s:
            if self.x0 is None:
                self.x0 = gt.q[0]
                self.t0 = t
            self.x_last, self.t_last = gt.q[0], t
            for i in (0, 1):
                if not gt.foot_contact[i] and self.prev_contact[i]:
                    self.lift_t[i] = t
                # a touchdown ends a real swing (airborne for MIN_SWING_S), not a contact flicker
                if (
                    gt.foot_contact[i]
                    and not self.prev_contact[i]
                    and self.lift_t[i] >= 0
                    and t - self.lift_t[i] >= MIN_SWING_S
                ):
                    self.touchdowns.append((t, np.asarray(gt.foot_pos[i], dtype=float)))
        self.prev_contact = list(gt.foot_contact)

    def outside(self) -> int:
        if not self.footholds:
            return 0
        return sum(
            not any(f.contains_xy(p[0], p[1]) for f in self.footholds) for _, p in self.touchdowns
        )


def _verdict(trial: Trial, judge: Judge, launch: list[str]) -> Trial:
    """Fill the trial's figures from what the judge saw."""
    vx = trial.commanded_velocity_mps
    trial.duration_s = judge.t_last
    trial.fell = judge.fall_t is not None
    trial.fall_time_s = judge.fall_t if judge.fall_t is not None else -1.0
    trial.min_pelvis_height_m = float(judge.min_z)
    if judge.x0 is not None:
        trial.distance_m = float(judge.x_last - judge.x0)
        span = judge.t_last - judge.t0
        trial.mean_velocity_mps = trial.distance_m / span if span > 0 else 0.0
    trial.velocity_error_ratio = (abs(trial.mean_velocity_mps - vx) / abs(vx)) if vx else 0.0
    trial.footsteps = len(judge.touchdowns)
    trial.footsteps_outside = judge.outside()
    trial.success = (
        not trial.fell
        and trial.velocity_error_ratio <= SPEED_TOLERANCE
        and trial.footsteps_outside == 0
        and trial.footsteps > 0
    )
    if "osc" not in launch:
        trial.notes.append("no walking controller in the experiment profile")
    return trial


