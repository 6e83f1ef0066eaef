"""The MPFC node, fed robot states in the deterministic harness, keeps the gait of Fig. 4."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from lcmtypes import mpfc_output_t, robot_state_t
from processes.kinematics import load_model
from processes.mpfc.process import GAIT_DS, GAIT_SS
from runtime.builder import build_node
from runtime.config_types import ProcessConfig
from runtime.errors import ConfigError
from runtime.harness import Binding, Harness
from runtime.node import Node


class StateReplay(Node):
    """Publishes a standing Cassie's state at 200 Hz, CoM drifting forward at ``speed``."""

    name = "replay"
    outputs = {"state": robot_state_t}

    def __init__(self, speed: float, contact=None) -> None:  # type: ignore[no-untyped-def]
        self.contact = contact  # t -> [left down, right down] (None: no contact flags)
        self.m = load_model()
        d = mujoco.MjData(self.m)
        mujoco.mj_resetDataKeyframe(self.m, d, 0)
        self.q0 = d.qpos.copy()
        self.speed = speed
        self.period_s = 0.005

    def tick(self, ctx, inbox) -> None:  # type: ignore[no-untyped-def]
        t = ctx.now_utime * 1e-6
        q = self.q0.copy()
        q[0] += self.speed * t
        v = np.zeros(self.m.nv)
        v[0] = self.speed
        msg = robot_state_t()
        msg.header.utime = ctx.now_utime
        msg.num_positions, msg.num_velocities, msg.num_motors = self.m.nq, self.m.nv, 10
        msg.q, msg.v, msg.motor_torque = q.tolist(), v.tolist(), [0.0] * 10
        if self.contact is not None:
            msg.in_contact = list(self.contact(t))
        ctx.publish("state", msg)


def _proc(**params) -> ProcessConfig:  # type: ignore[no-untyped-def]
    from runtime.config import HW_CONFIG_DIR

    return ProcessConfig(
        name="mpfc",
        host="laptop",
        module="processes.mpfc.process",
        source_file=HW_CONFIG_DIR / "processes.yaml",
        params=params,
        gains_file=HW_CONFIG_DIR / "gains" / "mpfc.yaml",
    )


def _run(seconds: float, contact=None, footholds_msg=None, **params):  # type: ignore[no-untyped-def]
    from runtime.config import HW_CONFIG_DIR

    profile = type("P", (), {"resolve": lambda self, p: HW_CONFIG_DIR / p,
                             "mode": "lockstep"})()  # the harness steps it in sim time
    node = build_node(_proc(**params), profile)
    h = Harness(
        [
            Binding(StateReplay(0.3, contact), inputs={}, outputs={"state": "S"}),
            Binding(
                node,
                inputs={"state": "S", "footholds": "F", "elevation_map": "E", "command": "C"},
                outputs={"plan": "P", "debug": "D"},
            ),
        ]
    )
    plans: list[mpfc_output_t] = []
    h.tap("P", lambda t, m: plans.append(m))
    if footholds_msg is not None:  # (as the sim publishes its terrain's truth)
        h.inject("F", footholds_msg, at_us=0)
    h.run_until(int(seconds * 1e6))
    return node, plans


def test_gait_alternates_stance_with_step_durations_within_bounds():
    node, plans = _run(3.0, footholds="flat")
    assert len(plans) == 601
    assert all(p.solve_status == 0 for p in plans)
    # touchdowns start the double-stance phases; each phase's [prev, next) switch times bound it
    touchdowns = sorted({round(p.prev_switch_time_s, 6) for p in plans
                         if p.gait_state in GAIT_DS})
    steps = np.diff(touchdowns)
    p = node.params
    # each MPFC stance phase = double stance T_ds + single stance in [t_min, t_max] (Sec. IV-D)
    assert len(steps) >= 6
    assert np.all(steps >= p.t_ds_s + p.t_ss_min_s - 0.006)
    assert np.all(steps <= p.t_ds_s + p.t_ss_max_s + 0.006)
    stances = [pl.stance for pl in plans]
    changes = [i for i in range(1, len(stances)) if stances[i] != stances[i - 1]]
    assert len(changes) == len(touchdowns) - 1
    # double stance lasts T_ds after each touchdown and ends at the liftoff, then single stance
    # runs from the liftoff to the planned touchdown
    for pl in plans:
        t = pl.header.utime * 1e-6
        assert pl.prev_switch_time_s <= t + 1e-9
        if pl.gait_state in GAIT_DS:
            assert t - pl.prev_switch_time_s < p.t_ds_s + 1e-9
            assert abs(pl.next_switch_time_s - pl.prev_switch_time_s - p.t_ds_s) < 1e-9
        else:
            assert pl.gait_state == GAIT_SS[pl.stance]
            liftoff = pl.prev_switch_time_s
            assert round(liftoff - p.t_ds_s, 6) in touchdowns
            assert p.t_ss_min_s - 0.006 <= pl.next_switch_time_s - liftoff <= p.t_ss_max_s + 0.006
        assert all(math.isfinite(x) for x in pl.next_footstep_world)
        assert abs(pl.ankle_torque) <= p.ankle_torque_max_nm + 1e-6


def test_footsteps_land_on_ground_truth_stones():
    from sim import terrain as sim_terrain

    truth = sim_terrain.foothold_set_msg(sim_terrain.generate("stones"))
    node, plans = _run(2.0, footholds="channel", footholds_msg=truth)
    assert node.footholds, "the stones terrain gave no footholds"
    last = plans[-1]
    step = np.array(last.next_footstep_world)
    stance = np.array(last.stance_foot_world)
    on = [f for f in node.footholds if f.contains(np.r_[step[:2], f.height_at(step[:2])], 1e-4)]
    assert on, "the footstep is on no stone"
    # heights are relative to the stone under the stance foot (foothold_anchor_m): the step's
    # z is the stance foot's z plus the height difference between the two stones
    under = [f for f in node.footholds
             if f.contains(np.r_[stance[:2], f.height_at(stance[:2])], 0.05)]
    if under:
        rise = on[0].height_at(step[:2]) - under[0].height_at(stance[:2])
        assert abs(step[2] - (stance[2] + rise)) < 1e-6


def test_bad_foothold_source_names_the_key():
    with pytest.raises(ConfigError, match=r"processes\.mpfc\.params\.footholds"):
        _run(0.1, footholds="lidar")


def test_a_restart_mid_step_waits_for_the_touchdown_and_takes_the_robots_stance():
    # the robot on its left foot, the right in the air until it lands at t = 0.2 s
    _, plans = _run(0.5, contact=lambda t: (True, t >= 0.2), footholds="flat")
    assert plans, "no plan after the touchdown"
    first = plans[0]
    assert abs(first.header.utime * 1e-6 - 0.2) < 0.006  # nothing planned from a swinging foot
    assert first.stance == 1 and first.gait_state in GAIT_DS  # the right foot just landed
    assert abs(first.prev_switch_time_s - first.header.utime * 1e-6) < 1e-9


def test_a_start_with_both_feet_down_begins_on_the_left_foot_at_once():
    _, plans = _run(0.1, contact=lambda t: (True, True), footholds="flat")
    assert plans[0].header.utime == 0 and plans[0].stance == 0
