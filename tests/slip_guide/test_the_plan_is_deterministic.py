"""The same inputs give the same plan, to the bit: no state is kept between plans and the
candidate search breaks distance ties by index."""

from __future__ import annotations

import numpy as np

from processes.slip_guide.planner import SlipPlanner
from tools.testbed.slip_scenes import problem, scene


def test_two_plans_of_the_same_inputs_are_identical(slip_params) -> None:
    s_ref, v_ref, cands = problem(scene("stones", 3), slip_params)
    planner = SlipPlanner(slip_params)
    a = planner.plan(s_ref[0], v_ref[0], s_ref, v_ref, cands)
    b = SlipPlanner(slip_params).plan(s_ref[0], v_ref[0], s_ref, v_ref, cands)
    c = planner.plan(s_ref[0], v_ref[0], s_ref, v_ref, cands)
    for other in (b, c):
        assert other.card_history == a.card_history
        np.testing.assert_array_equal(other.step, a.step)
        np.testing.assert_array_equal(other.point, a.point)
        np.testing.assert_array_equal(other.alpha, a.alpha)
        np.testing.assert_array_equal(other.s, a.s)
