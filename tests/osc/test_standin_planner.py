"""The OSC's own footstep planner while the MPFC's plans are lost (``StandInPlanner``): it
lands the swing in progress where the MPFC sent it, and steps in place on the ground each foot
stood on."""

from __future__ import annotations

import numpy as np

from lcmtypes import mpfc_output_t
from processes.osc.model import CassieModel
from processes.osc.standin_planner import StandInPlanner


def _last_plan(q: np.ndarray, model: CassieModel) -> mpfc_output_t:
    """An MPFC plan 0.1 s into left single stance, sending the right foot 0.3 m ahead."""
    model.update(q, np.zeros(model.nv))
    left = model.foot_center(0)
    msg = mpfc_output_t()
    msg.gait_state = 0  # left single stance
    msg.stance = 0
    msg.stance_foot_world = left.tolist()
    msg.next_footstep_world = [left[0] + 0.3, left[1] - 0.2, left[2]]
    msg.prev_switch_time_s = 1.0
    msg.next_switch_time_s = 1.3
    msg.stance_yaw = 0.0
    return msg


def test_the_swing_in_progress_lands_where_the_mpfc_sent_it(sim_model, q_stand):
    model = CassieModel(sim_model)
    plan = _last_plan(q_stand, model)
    planner = StandInPlanner(CassieModel(sim_model), measured_ground=True)
    planner.seed(plan)
    v = np.zeros(model.nv)
    v[0] = 0.4  # walking on: a one-step stop would ask for a much longer step
    for t in (1.1, 1.2, 1.29):
        own = planner.plan(t, q_stand, v)
        np.testing.assert_allclose(own.next_footstep_world, plan.next_footstep_world)
    after = planner.plan(1.31, q_stand, v)  # the seeded step has landed: its own plans now
    assert int(after.stance) == 1
    assert not np.allclose(after.next_footstep_world, plan.next_footstep_world)


def test_stepping_in_place_keeps_each_foot_on_the_ground_it_stood_on(sim_model, q_stand):
    """A foot read at its planned touchdown while still in the air does not raise the ground:
    the heights come from each foot while it stood."""
    model = CassieModel(sim_model)
    plan = _last_plan(q_stand, model)
    planner = StandInPlanner(CassieModel(sim_model), measured_ground=True)
    planner.seed(plan)
    z_ground = [float(model.foot_center(s)[2]) for s in (0, 1)]
    q_air = q_stand.copy()
    q_air[2] += 0.03  # the whole robot 3 cm up: every foot reads 3 cm above its ground
    own = planner.plan(1.1, q_stand, np.zeros(model.nv))
    touchdowns = []
    for _ in range(8):  # four steps: each touchdown read 3 cm up, each liftoff on the ground
        t = float(own.next_switch_time_s) + 1e-4
        touching_down = int(own.gait_state) in (0, 1)
        own = planner.plan(t, q_air if touching_down else q_stand, np.zeros(model.nv))
        if touching_down:
            touchdowns.append((int(own.stance), float(own.stance_foot_world[2])))
    # the right foot, never seen standing before its first touchdown, reads 3 cm high once;
    # from then on every stance is on the ground its foot stood on
    assert touchdowns[0] == (1, touchdowns[0][1]) and abs(touchdowns[0][1] - 0.03) < 1e-9
    for side, z in touchdowns[1:]:
        assert abs(z - z_ground[side]) < 1e-9, touchdowns
    # ... and each swing aims at the ground it lifted off from
    assert abs(float(own.next_footstep_world[2]) - z_ground[1 - int(own.stance)]) < 1e-9
