"""The judge of a walking trial: its figures (``Trial``) and how they are judged from the sim's
ground truth (falls, distance, speed against the command, footsteps outside every foothold,
whether the robot reached the course's end).

The success rule. On a course with an end (stones, beam, stairs: its last surface, the far
platform or the landing) a trial succeeds when the robot reaches that surface (its pelvis
``GOAL_PAST_M`` past the surface's near edge) without a fall and with no footstep outside a
foothold; it is "crossed" when it reaches it without a fall, footsteps aside (the paper's plain
traversal). On flat ground (no end) it succeeds with no fall, the mean speed within 15 % of the
command and no footstep outside; crossed is no fall.

Beside the verdict, how each foot landed against the footstep planner's last target for it
(the plan channel's ``next_footstep_world``) and how late that target last moved: where a
footstep outside a foothold came from a target the swing could not follow, or a swing that
missed a settled one."""

from __future__ import annotations

import bisect
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from lcmtypes import mpfc_output_t

STANDING_GAIT = mpfc_output_t.GAIT_STANDING  # a plan that takes no step
FALL_HEIGHT_M = 0.6
MIN_SWING_S = 0.1  # shorter airborne spells are contact flicker, not steps
HEADING_GAIN = 1.0  # operator's yaw rate per radian of heading error (Section VIII-A)
SPEED_TOLERANCE = 0.15
#: the mean speed is measured from this long after the release: the start (the weight shift
#: onto the first stance foot and the first steps' acceleration) is not walking at the command
SPEED_FROM_S = 1.0
GOAL_PAST_M = 0.15  # the pelvis this far onto the course's last surface: it has crossed
HALT_BEFORE_FALL_S = 0.4  # a stop that began this long before a fall (a step) preceded it
#: ... and with the CoM slower than this (horizontal, m/s): walking on Table I's stones at
#: 0.375 m/s the long steps bring it to 0.8-0.9 m/s; a stop begun at 1.1-1.4 m/s came after a
#: 0.7-1.06 m step that had already thrown the robot (measured, d_min 40-50 cm), not before
HALT_MAX_SPEED_MPS = 1.0
#: a footstep's planned target counts as moved when it shifts this far from where it last
#: moved to (m; the MPFC re-solves at 200 Hz and its footstep wanders by millimetres)
TARGET_MOVE_M = 0.01
#: a touchdown whose target moved less than this before it had a late target (s): a swing
#: (0.3 s, Table V) cannot follow a move that late (Opt-T's targets with perception moved
#: 35-125 ms before touchdown where a foot landed off its stone; Fixed-T's settle 0.28 s or
#: more before: measured, d_min 45 cm seed 2009)
LATE_TARGET_S = 0.1


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
    #: the course's end (its last surface's near edge, x), None on a course without one
    goal_x_m: float | None = None
    reached_goal_s: float = -1.0  # when the pelvis got GOAL_PAST_M past it (-1: never)
    crossed: bool = False  # reached the end (or, without one, the whole trial) without a fall
    #: the MPFC's stops for no foothold ahead within a step, whether it was stopping (or
    #: standing) for that at the end and since when (s; -1: it was not)
    halts: int = 0
    halted_at_end: bool = False
    halt_s: float = -1.0
    #: the stop began with the stance foot on a true foothold (not off the course, falling)
    halt_on_foothold: bool = True
    #: the CoM's horizontal speed when that stop began (m/s; 0 without a stop)
    halt_speed_mps: float = 0.0
    #: both feet on true footholds (the sim's, less 2 cm) when that stop began: a stop with a
    #: foot already on an edge or in the pit is one the robot began falling into
    halt_feet_on_footholds: bool = True
    #: where each foot touched down against the footstep planner's last target for it (its
    #: plan's next_footstep_world, horizontal): median, 90th percentile, largest (m); the
    #: touchdowns with a target, and those whose target had moved within LATE_TARGET_S of
    #: it (-1 and 0 without plans: a trial without the MPFC, a record made before)
    landing_error_median_m: float = -1.0
    landing_error_p90_m: float = -1.0
    landing_error_max_m: float = -1.0
    landings: int = 0
    late_targets: int = 0

    @property
    def fell_while_stopped(self) -> bool:
        """A fall in a stop the MPFC began a step or more before it (nothing ahead was
        reachable) with both feet on the course and the CoM at a walking speed, not one that
        the fall itself began (a robot on the ground, a foot off the beam or on a stone's edge
        or a CoM thrown at 1.3 m/s by the step before has nothing ahead either)."""
        return fell_in_a_stop(self.fell, self.fall_time_s, self.halt_s, self.halt_on_foothold,
                              self.halt_speed_mps, self.halt_feet_on_footholds)
    wall_s: float = 0.0
    mode: str = "harness"  # harness (deterministic, one process), lockstep or realtime (launch)
    timing: dict[str, dict[str, Any]] = field(default_factory=dict)  # live runs: report's loops
    cpu: dict[str, Any] = field(default_factory=dict)  # live runs: the report's CPU table
    realtime: dict[str, Any] = field(default_factory=dict)  # live runs: real-time checks
    notes: list[str] = field(default_factory=list)



def fell_in_a_stop(fell: bool, fall_time_s: float, halt_s: float, on_foothold: bool,
                   halt_speed_mps: float, feet_on_footholds: bool = True) -> bool:
    """``Trial.fell_while_stopped`` from its fields (also for sweep records)."""
    return (fell and on_foothold and feet_on_footholds and halt_speed_mps <= HALT_MAX_SPEED_MPS
            and 0.0 <= halt_s <= fall_time_s - HALT_BEFORE_FALL_S)


class Judge:
    """Watches GROUND_TRUTH: falls, distance, speed and where each foot touches down."""

    def __init__(self, footholds: list[Any], walk_start_s: float,
                 ground: Callable[[float, float], float] | None = None,
                 goal_x: float | None = None) -> None:
        self.footholds = footholds
        self.goal_x = goal_x
        self.goal_t: float | None = None
        self.walk_start_s = walk_start_s
        #: height of the terrain under (x, y): a fall is the pelvis below FALL_HEIGHT_M over
        #: it (on stairs a robot lying on the landing has its pelvis above 0.6 m)
        self.ground = ground if ground is not None else (lambda x, y: 0.0)
        self.x0: float | None = None
        self.speed_x0: float | None = None  # where and when the speed's window starts
        self.speed_t0 = 0.0
        self.x_last = 0.0
        self.t_last = 0.0
        self.min_z = np.inf
        self.fall_t: float | None = None
        self.prev_contact = [True, True]
        self.lift_t = [-1.0, -1.0]  # when each foot last left the ground
        self.touchdowns: list[tuple[float, np.ndarray]] = []
        #: per foot, the planner's newest target for it (world xy), where and when it last
        #: moved by TARGET_MOVE_M; and per touchdown with a target: (t, foot, error m,
        #: seconds since its target last moved)
        self._target: list[np.ndarray | None] = [None, None]
        self._moved: list[tuple[np.ndarray, float] | None] = [None, None]
        self.landings: list[tuple[float, int, float, float]] = []
        self._speed: list[tuple[float, float]] = []  # (t, CoM horizontal speed) per message
        self._feet: list[tuple[float, float, float, float]] = []  # (xl, yl, xr, yr) ditto

    def on_plan(self, t_us: int, plan: Any) -> None:
        """The footstep planner's plan (``mpfc_output_t``): its swing foot's target, and when
        that target last moved. A standing plan has no step to take."""
        if int(plan.gait_state) == STANDING_GAIT or int(plan.stance) not in (0, 1):
            return
        t = plan.header.utime * 1e-6
        swing = 1 - int(plan.stance)
        xy = np.array(plan.next_footstep_world[:2], dtype=float)
        if not np.all(np.isfinite(xy)):
            return
        self._target[swing] = xy
        moved = self._moved[swing]
        if moved is None or math.hypot(*(xy - moved[0])) > TARGET_MOVE_M:
            self._moved[swing] = (xy, t)

    def _landed(self, t: float, foot: int, pos: np.ndarray) -> None:
        """A touchdown of ``foot`` at ``pos``: its error against the target planned for it,
        which is then spent."""
        target, moved = self._target[foot], self._moved[foot]
        if target is not None and moved is not None:
            self.landings.append((t, foot, math.hypot(pos[0] - target[0], pos[1] - target[1]),
                                  t - moved[1]))
        self._target[foot] = self._moved[foot] = None

    def on_foothold(self, x: float, y: float) -> bool:
        """(x, y) lies on a foothold of the course (False without footholds)."""
        return any(f.contains_xy(x, y) for f in self.footholds)

    def _message_at(self, t: float) -> int:
        """Index of the first message at or after sim time ``t`` (the last one past them);
        only with messages."""
        return min(bisect.bisect_left(self._speed, (t, -math.inf)), len(self._speed) - 1)

    def speed_at(self, t: float) -> float:
        """The CoM's horizontal speed at sim time ``t`` (the first message at or after it;
        0 before any)."""
        return self._speed[self._message_at(t)][1] if self._speed else 0.0

    def feet_on_footholds_at(self, t: float) -> bool:
        """Both feet (the sim's foot positions in the first message at or after sim time
        ``t``) lie on a foothold of the course (True without footholds or messages)."""
        if not self.footholds or not self._speed:
            return True
        xl, yl, xr, yr = self._feet[self._message_at(t)]
        return self.on_foothold(xl, yl) and self.on_foothold(xr, yr)

    def __call__(self, t_us: int, gt: Any) -> None:
        t = gt.header.utime * 1e-6
        self._speed.append((t, math.hypot(gt.com_vel[0], gt.com_vel[1])))
        fl, fr = gt.foot_pos[0], gt.foot_pos[1]
        self._feet.append((fl[0], fl[1], fr[0], fr[1]))
        z = gt.q[2] - self.ground(gt.q[0], gt.q[1])
        self.min_z = min(self.min_z, z)
        if z < FALL_HEIGHT_M and self.fall_t is None:
            self.fall_t = t
        if t >= self.walk_start_s:
            if self.x0 is None:
                self.x0 = gt.q[0]
                self.t0 = t
            if self.speed_x0 is None and t >= self.t0 + SPEED_FROM_S:
                self.speed_x0, self.speed_t0 = gt.q[0], t
            self.x_last, self.t_last = gt.q[0], t
            if (self.goal_t is None and self.goal_x is not None and self.fall_t is None
                    and gt.q[0] >= self.goal_x + GOAL_PAST_M):
                self.goal_t = t
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
                    self._landed(t, i, self.touchdowns[-1][1])
        self.prev_contact = list(gt.foot_contact)

    def finished(self, linger_s: float = 2.0) -> bool:
        """The trial has nothing more to show: a fall, or ``linger_s`` after reaching the end
        (time to stop on the last surface, or to step off it)."""
        return self.fall_t is not None or (
            self.goal_t is not None and self.t_last >= self.goal_t + linger_s)

    def outside(self) -> int:
        if not self.footholds:
            return 0
        return sum(not self.on_foothold(p[0], p[1]) for _, p in self.touchdowns)


def _verdict(trial: Trial, judge: Judge, launch: list[str]) -> Trial:
    """Fill the trial's figures from what the judge saw."""
    vx = trial.commanded_velocity_mps
    trial.duration_s = judge.t_last
    trial.fell = judge.fall_t is not None
    trial.fall_time_s = judge.fall_t if judge.fall_t is not None else -1.0
    trial.min_pelvis_height_m = float(judge.min_z)
    if judge.x0 is not None:
        trial.distance_m = float(judge.x_last - judge.x0)
        if judge.speed_x0 is not None and judge.t_last > judge.speed_t0:
            trial.mean_velocity_mps = float((judge.x_last - judge.speed_x0)
                                            / (judge.t_last - judge.speed_t0))
    trial.velocity_error_ratio = (abs(trial.mean_velocity_mps - vx) / abs(vx)) if vx else 0.0
    trial.footsteps = len(judge.touchdowns)
    trial.footsteps_outside = judge.outside()
    if judge.landings:
        err = np.array([e for _, _, e, _ in judge.landings])
        trial.landing_error_median_m = float(np.median(err))
        trial.landing_error_p90_m = float(np.percentile(err, 90))
        trial.landing_error_max_m = float(err.max())
        trial.landings = len(err)
        trial.late_targets = sum(s < LATE_TARGET_S for _, _, _, s in judge.landings)
    trial.goal_x_m = judge.goal_x
    trial.reached_goal_s = judge.goal_t if judge.goal_t is not None else -1.0
    if judge.goal_x is None:
        trial.crossed = not trial.fell
        trial.success = (trial.crossed and trial.velocity_error_ratio <= SPEED_TOLERANCE
                         and trial.footsteps_outside == 0 and trial.footsteps > 0)
    else:
        trial.crossed = not trial.fell and judge.goal_t is not None
        trial.success = trial.crossed and trial.footsteps_outside == 0
    if "osc" not in launch:
        trial.notes.append("no walking controller in the experiment profile")
    return trial


