"""The judge's success rule on a course with an end: reaching the last surface without a fall
and with every footstep on a foothold, whatever the speed (the robot stops there); a fall
before it is neither success nor crossed; flat ground keeps the speed rule."""

from __future__ import annotations

import numpy as np

from lcmtypes import ground_truth_t
from runtime.geometry import Foothold
from tools.experiment.judge import GOAL_PAST_M, Judge, Trial, _verdict


def _gt(t: float, x: float, z: float = 0.95, left_up: bool = False) -> ground_truth_t:
    m = ground_truth_t()
    m.header.utime = int(t * 1e6)
    m.num_positions, m.num_velocities = 7, 6
    m.q = [x, 0.0, z, 1.0, 0.0, 0.0, 0.0]
    m.v = [0.0] * 6
    m.foot_contact = [not left_up, True]
    m.foot_pos = [[x, 0.1, 0.0], [x, -0.1, 0.0]]
    return m


def _judge(xs: list[float], zs: list[float] | None = None, goal: float | None = 2.0) -> Trial:
    ground = Foothold.from_polygon(np.array([[-5.0, -1.0], [5.0, -1.0], [5.0, 1.0], [-5.0, 1.0]]))
    j = Judge([ground], 0.0, goal_x=goal)
    for i, x in enumerate(xs):
        j(0, _gt(0.5 * i, x, (zs or [0.95] * len(xs))[i], left_up=i % 2 == 1))
    return _verdict(Trial("stones", 0, commanded_velocity_mps=0.375), j, ["osc"])


def test_reaching_the_end_and_stopping_there_succeeds_whatever_the_mean_speed() -> None:
    tr = _judge([0.0, 0.5, 1.0, 1.5, 2.0 + GOAL_PAST_M] + [2.2] * 12)
    assert tr.crossed and tr.success and tr.reached_goal_s == 2.0
    assert tr.velocity_error_ratio > 0.15  # it stood at the end: slower than the command


def test_a_fall_before_the_end_is_neither_crossed_nor_a_success() -> None:
    tr = _judge([0.0, 0.5, 1.0, 1.2], zs=[0.95, 0.95, 0.95, 0.3])
    assert tr.fell and not tr.crossed and not tr.success and tr.reached_goal_s == -1.0


def test_without_an_end_the_speed_rule_decides() -> None:
    slow = _judge([0.0, 0.05, 0.1, 0.15], goal=None)
    assert slow.crossed and not slow.success
    assert _judge([0.1875 * i for i in range(6)], goal=None).success
