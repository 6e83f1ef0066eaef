"""processes.mpfc.gait.GaitClock, with no LCM: the gait timed from touchdowns (Fig. 4), a
start with a foot in the air waiting for that foot's touchdown, and a solution's stance time
taken only after double stance."""

from __future__ import annotations

import pytest

from processes.mpfc.gait import LEFT, RIGHT, GaitClock

T_SS, T_DS = 0.30, 0.10


def test_a_standing_start_is_a_left_touchdown_and_the_stances_swap_on_schedule() -> None:
    c = GaitClock(T_SS + T_DS)
    assert c.advance(1.0, (True, True)) and c.stance == LEFT
    assert c.remaining(1.1) == pytest.approx(0.3)
    assert c.phase(1.05, T_DS) == (True, 1.0, pytest.approx(1.1))  # double stance
    assert c.phase(1.2, T_DS) == (False, pytest.approx(1.1), pytest.approx(1.4))
    assert not c.advance(1.4, (True, True)) and c.stance == RIGHT  # the planned touchdown
    assert c.touchdown_s == pytest.approx(1.4) and c.remaining(1.9) == 0.0


def test_a_start_mid_step_waits_for_the_air_foot_to_land_and_stands_on_it() -> None:
    c = GaitClock(T_SS + T_DS)
    assert not c.advance(0.0, (True, False)) and c.stance is None  # right foot swinging
    assert not c.advance(0.1, (True, False)) and c.stance is None
    assert c.advance(0.2, (True, True)) and c.stance == RIGHT and c.touchdown_s == 0.2


def test_a_solution_moves_the_touchdown_only_after_double_stance() -> None:
    c = GaitClock(T_SS + T_DS)
    c.advance(0.0, (True, True))
    c.plan_touchdown(0.05, 0.2, T_DS)  # in double stance: ignored
    assert c.next_touchdown_s == pytest.approx(0.4)
    c.plan_touchdown(0.15, 0.2, T_DS)
    assert c.next_touchdown_s == pytest.approx(0.35)


def test_a_standing_start_holds_double_stance_for_the_weight_shift_and_then_times_as_usual(
) -> None:
    c = GaitClock(T_SS + T_DS, T_DS, start_ds_s=0.4)
    assert c.advance(1.0, (True, True), at_rest=True) and c.stance == LEFT
    assert c.phase(1.35, T_DS) == (True, 1.0, pytest.approx(1.4))  # still double stance
    assert c.remaining(1.2) == pytest.approx(T_SS + T_DS)  # planned as at a touchdown
    assert c.remaining(1.4) == pytest.approx(T_SS)  # the lift-off: T_ss left
    c.plan_touchdown(1.3, 0.1, T_DS)  # in the long double stance: ignored
    assert c.next_touchdown_s == pytest.approx(1.7)
    assert not c.advance(1.7, (True, True)) and c.stance == RIGHT
    assert c.phase(1.75, T_DS) == (True, pytest.approx(1.7), pytest.approx(1.8))  # T_ds again


def test_a_start_while_moving_takes_no_weight_shift() -> None:
    c = GaitClock(T_SS + T_DS, T_DS, start_ds_s=0.4)
    assert c.advance(1.0, (True, True), at_rest=False)
    assert c.phase(1.15, T_DS)[0] is False and c.next_touchdown_s == pytest.approx(1.4)


def test_walking_on_from_standing_takes_the_starts_weight_shift_on_the_same_stance() -> None:
    c = GaitClock(T_SS + T_DS, T_DS, start_ds_s=0.4)
    c.advance(0.0, (True, True), at_rest=False)
    for t in (0.4, 0.8, 1.2):  # stood in a stop: the clock went on swapping stances
        c.advance(t, (True, True))
    stance = c.stance
    c.from_standing(1.2)  # the way on found at this touchdown, the robot at rest
    assert c.stance == stance
    assert c.phase(1.55, T_DS) == (True, pytest.approx(1.2), pytest.approx(1.6))  # shifting
    assert c.remaining(1.4) == pytest.approx(T_SS + T_DS)
    assert not c.advance(1.85, (True, True)) and c.stance == stance  # its swing (to 1.9)
    assert not c.advance(1.95, (True, True)) and c.stance == 1 - stance
