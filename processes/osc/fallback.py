"""``PlanFallback``: the OSC's own footstep plan while the MPFC's are lost.

When the MPFC dies (a crash, a kill, a restart that takes seconds: numba's start-up) or
stalls, walking on its last plan ends in a fall, and so did latching safe mode (joint damping)
after ``plan_timeout_s``. Instead, once the newest plan is older than ``after_s`` while
walking, the OSC plans its own steps with the ALIP stand-in (``standin_planner``): seeded
from the last plan, so the swing in progress lands where the MPFC sent it, then stepping in
place (desired velocity 0) on the ground it stands on. The MPFC gets the robot back when a
fresh plan of its is in double stance on the same new stance foot as the robot is: the gait
phases agree, so the hand-back is a plan like the next one. Two gaits of the same period
may never agree by themselves (measured live: 23 s of stepping in place after a restart,
then a fall), so once the MPFC is back the robot waits in double stance, up to
``MAX_HOLD_S``, for the MPFC's gait to come round to its stance foot.

(Standing would be the quieter wait; stepping in place keeps a gait the MPFC can take back
without the stand-to-walk hand-over, and is what was measured: see docs/reports/faults.md.)
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .controller import WALKING
from .model import CassieModel
from .standin_planner import StandInPlanner
from .walking import DOUBLE_AFTER_LEFT, DOUBLE_AFTER_RIGHT

#: mpfc_output_t.gait_state of double stance after a left / right touchdown
_DS = (DOUBLE_AFTER_LEFT, DOUBLE_AFTER_RIGHT)
#: the longest wait in double stance for the MPFC's gait (more than its two-step period)
MAX_HOLD_S = 1.0


def plan_age_s(t_s: float, plan: Any | None) -> float:
    """Seconds since the state ``plan`` was computed from (inf: no plan)."""
    if plan is None:
        return float("inf")
    return t_s - float(plan.header.utime) * 1e-6


class PlanFallback:
    """Decides, per tick, which plan the controller follows: the MPFC's, or its own."""

    def __init__(self, model: CassieModel, after_s: float) -> None:
        self.after_s = after_s
        self._model = CassieModel(model.m)  # its own data: the planner updates kinematics
        self.active = False
        self.engaged = 0  # times the fallback took over
        self.handed_back = 0  # ... and gave the robot back to the MPFC
        self.planner: StandInPlanner | None = None
        self._last_good: Any | None = None
        self._hold_since: float | None = None  # when this double stance's wait began

    def step(self, t_s: float, q: np.ndarray, v: np.ndarray, plan: Any | None,
             mode: int) -> Any | None:
        """The plan for this tick, given the MPFC's newest ``plan`` and the controller's
        ``mode`` before this tick."""
        fresh = plan_age_s(t_s, plan) <= self.after_s
        if fresh:
            self._last_good = plan
        if self.active:
            own = self._own(t_s, q, v)
            if fresh and self._agrees(plan, own):  # the MPFC is back, in step with the robot
                self.active = False
                self.handed_back += 1
                assert self.planner is not None
                self.planner.hold_double = False
                return plan
            self._wait(t_s, fresh, own)
            return own
        if fresh or mode != WALKING or self._last_good is None:
            return plan
        self.active = True  # walking, and the plans stopped: take over
        self.engaged += 1
        self.planner = StandInPlanner(self._model, vdes=(0.0, 0.0), measured_ground=True)
        self.planner.seed(self._last_good)
        return self._own(t_s, q, v)

    def _wait(self, t_s: float, fresh: bool, own: Any) -> None:
        """Hold the robot's double stance while the MPFC is back but out of step (at most
        ``MAX_HOLD_S`` per double stance), so that its gait comes round to this stance."""
        assert self.planner is not None
        in_ds = int(own.gait_state) in _DS
        if not in_ds:
            self._hold_since = None
        elif fresh and self._hold_since is None:
            self._hold_since = t_s
        holding = (fresh and in_ds and self._hold_since is not None
                   and t_s - self._hold_since < MAX_HOLD_S)
        self.planner.hold_double = holding

    @staticmethod
    def _agrees(plan: Any, own: Any) -> bool:
        """Both plans in double stance on the same new stance foot."""
        return (int(plan.gait_state) in _DS and int(own.gait_state) in _DS
                and int(plan.stance) == int(own.stance))

    def _own(self, t_s: float, q: np.ndarray, v: np.ndarray) -> Any:
        assert self.planner is not None
        return self.planner.plan(t_s, q, v)
