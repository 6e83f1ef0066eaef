"""Section III-B: with the force along the approximate leg (13), a candidate whose force
direction leaves the friction cone (3) is dropped before the QP, and gets no force."""

from __future__ import annotations

import dataclasses

import numpy as np

from processes.slip_guide.candidates import in_friction_cone
from processes.slip_guide.planner import SlipPlanner
from tools.testbed.slip_scenes import problem, scene


def test_a_leg_steeper_than_the_cone_is_kept_and_a_shallower_one_dropped() -> None:
    up = np.array([[0.0, 0.0, 1.0]] * 5)
    mu = 0.6
    legs = np.array([[0.0, 0.0, 0.85],  # straight up
                     [0.5, 0.0, 0.85],  # 0.59 tangential per normal: inside
                     [0.6, 0.0, 0.85],  # 0.71: outside
                     [0.3, 0.4, 0.85],  # 0.5 / 0.85 = 0.59 in the plane's two tangents
                     [0.0, 0.0, -0.2]])  # pulling: never
    np.testing.assert_array_equal(in_friction_cone(legs, up, mu),
                                  [True, True, False, True, False])


def test_on_a_slope_the_cone_turns_with_the_surface_normal() -> None:
    n = np.array([[np.sin(0.5), 0.0, np.cos(0.5)]])  # a 29 deg slope rising towards -x
    vertical = np.array([[0.0, 0.0, 1.0]])
    assert in_friction_cone(vertical, n, 0.6)  # tan(0.5) = 0.55 < 0.6
    assert not in_friction_cone(vertical, n, 0.5)


def test_the_plan_puts_no_force_on_a_dropped_candidate(slip_params) -> None:
    # on ice (mu 0.15) a leg more than ~13 cm off the vertical leaves the cone
    p = dataclasses.replace(slip_params, friction_mu=0.15)
    s_ref, v_ref, cands = problem(scene("flat", 0), p)
    plan = SlipPlanner(p).plan(s_ref[0], v_ref[0], s_ref, v_ref, cands)
    assert plan.status == "solved"
    assert (~plan.usable).any() and plan.usable.any()
    assert np.all(plan.alpha[~plan.usable] == 0.0)
    up = np.tile([0.0, 0.0, 1.0], (len(plan.leg), 1))
    np.testing.assert_array_equal(plan.usable, in_friction_cone(plan.leg, up, 0.15))
    assert np.all(in_friction_cone(plan.leg[plan.chosen], up[plan.chosen], 0.15))
