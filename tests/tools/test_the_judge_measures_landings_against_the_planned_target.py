"""The judge's landing figures: each touchdown against the planner's last target for that
foot, and whether that target moved too late for the swing to follow (``LATE_TARGET_S``);
a standing plan sets no target, and a target is spent by its touchdown."""

from __future__ import annotations

import pytest

from lcmtypes import ground_truth_t, mpfc_output_t
from tools.experiment.judge import LATE_TARGET_S, Judge, Trial, _verdict


def _plan(t: float, stance: int, target: tuple[float, float],
          gait: int | None = None) -> mpfc_output_t:
    m = mpfc_output_t()
    m.header.utime = round(t * 1e6)
    m.stance = stance
    m.gait_state = (mpfc_output_t.GAIT_LEFT_SS, mpfc_output_t.GAIT_RIGHT_SS)[stance] \
        if gait is None else gait
    m.next_footstep_world = [target[0], target[1], 0.0]
    return m


def _gt(t: float, contact: tuple[bool, bool], left: tuple[float, float],
        right: tuple[float, float]) -> ground_truth_t:
    m = ground_truth_t()
    m.header.utime = round(t * 1e6)
    m.num_positions, m.num_velocities = 7, 6
    m.q = [0.0, 0.0, 0.95, 1.0, 0.0, 0.0, 0.0]
    m.v = [0.0] * 6
    m.foot_contact = list(contact)
    m.foot_pos = [[left[0], left[1], 0.0], [right[0], right[1], 0.0]]
    return m


def test_a_touchdown_is_measured_against_its_target_and_a_late_move_is_counted() -> None:
    j = Judge([], walk_start_s=0.0)
    left, right = (0.0, 0.1), (0.0, -0.1)
    j(0, _gt(0.0, (True, True), left, right))
    # the left foot swings (stance right): its target settles at 0.30, then moves 5 cm at 0.25
    for k in range(6):
        j.on_plan(0, _plan(0.05 * k, 1, (0.30 + 0.002 * k, 0.1)))  # wanders by 2 mm a plan
    j(0, _gt(0.05, (False, True), left, right))
    j.on_plan(0, _plan(0.25, 1, (0.35, 0.1)))
    j(0, _gt(0.30, (True, True), (0.34, 0.1), right))  # lands 1 cm short, 50 ms after the move
    # the right foot swings (stance left) to a target settled 0.35 s before its touchdown;
    # a standing plan in between sets nothing
    j.on_plan(0, _plan(0.30, 0, (0.6, -0.1)))
    j.on_plan(0, _plan(0.40, 0, (5.0, 5.0), gait=mpfc_output_t.GAIT_STANDING))
    j(0, _gt(0.35, (True, False), (0.34, 0.1), right))
    j.on_plan(0, _plan(0.60, 0, (0.6, -0.1)))
    j(0, _gt(0.65, (True, True), (0.34, 0.1), (0.6, -0.12)))  # 2 cm out
    tr = _verdict(Trial("flat", 0, commanded_velocity_mps=0.375), j, ["osc"])
    assert tr.landings == 2 and tr.footsteps == 2
    assert tr.late_targets == 1  # the left one: moved 0.05 s before, under LATE_TARGET_S
    assert 0.05 < LATE_TARGET_S < 0.35
    assert tr.landing_error_max_m == pytest.approx(0.02)
    assert tr.landing_error_median_m == pytest.approx(0.015)


def test_without_plans_there_is_nothing_to_measure_and_a_spent_target_is_not_reused() -> None:
    j = Judge([], walk_start_s=0.0)
    j(0, _gt(0.0, (True, True), (0.0, 0.1), (0.0, -0.1)))
    j(0, _gt(0.1, (False, True), (0.0, 0.1), (0.0, -0.1)))
    j(0, _gt(0.4, (True, True), (0.2, 0.1), (0.0, -0.1)))
    tr = _verdict(Trial("flat", 0), j, ["osc"])
    assert tr.footsteps == 1 and tr.landings == 0 and tr.landing_error_median_m == -1.0
    j.on_plan(0, _plan(0.5, 1, (0.4, 0.1)))
    j(0, _gt(0.6, (False, True), (0.2, 0.1), (0.0, -0.1)))
    j(0, _gt(0.9, (True, True), (0.4, 0.1), (0.0, -0.1)))  # on its target
    j(0, _gt(1.0, (False, True), (0.4, 0.1), (0.0, -0.1)))
    j(0, _gt(1.3, (True, True), (0.6, 0.1), (0.0, -0.1)))  # no plan since: not measured
    tr = _verdict(Trial("flat", 0), j, ["osc"])
    assert tr.footsteps == 3 and tr.landings == 1 and tr.landing_error_max_m == 0.0
