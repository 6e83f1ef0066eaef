"""The OSC Node shell: stamps outputs with the state's utime, never publishes a NaN torque."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from lcmtypes import osc_debug_t, robot_state_t, torque_command_t
from runtime.builder import build_node
from runtime.cassie_packets import STATUS_HOLDER_ENGAGED
from runtime.config_types import ProcessConfig, Profile
from runtime.driver import NodeDriver
from runtime.errors import ConfigError

HW = Path(__file__).resolve().parents[2] / "hw_config"


def _profile() -> Profile:
    return Profile(name="test", path=HW / "none.yaml", hw_config_dir=HW, mode="lockstep",
                   lcm_url="udpm://239.255.76.67:7667?ttl=0", hosts={}, channels={},
                   processes={}, launch=())


def _proc(**params) -> ProcessConfig:
    return ProcessConfig(name="osc", host="nuc", module="processes.osc.process",
                         source_file=HW / "processes.yaml", params=dict(params),
                         gains_file=HW / "gains" / "osc.yaml")


def _state(q: np.ndarray, utime: int, held: bool = True) -> robot_state_t:
    """A state at ``utime``; ``held``: the target PC reports its start-up holder engaged."""
    s = robot_state_t()
    s.header.utime = utime
    s.target_status = STATUS_HOLDER_ENGAGED if held else 0
    s.num_positions, s.num_velocities, s.num_motors = 35, 32, 10
    s.q = q.tolist()
    s.v = [0.0] * 32
    s.motor_torque = [0.0] * 10
    return s


def _driver(**params) -> NodeDriver:
    """The OSC of ``params``, built and driven as a run of it (its inputs' edge checks)."""
    return NodeDriver.from_config(_proc(**params), _profile())


def test_node_publishes_torque_and_debug_stamped_with_the_state_utime(q_stand):
    d = _driver()
    assert d.tick(state=_state(q_stand, 123_456))
    tq, dbg = d.sent["torque"][-1], d.sent["debug"][-1]
    assert isinstance(tq, torque_command_t) and isinstance(dbg, osc_debug_t)
    assert tq.header.utime == 123_456 and dbg.header.utime == 123_456
    assert tq.num_motors == 10 and tq.mode == 1 and np.all(np.isfinite(tq.torque))
    assert dbg.qp_status == 1 and dbg.num_tasks == len(dbg.task_names) > 0


def test_node_with_nan_or_malformed_state_publishes_finite_safe_torques(q_stand):
    """A NaN state never reaches the node: the edge check rejects it and there is no tick
    on it. Behind the edge (its check off) the node answers one itself with finite safe
    torques, as it does a state of the wrong size (which passes here, with no ``limits``;
    hw_config's size limits reject it at the edge too)."""
    d = _driver()
    q = q_stand.copy()
    q[2] = np.nan
    assert not d.tick(state=_state(q, 1000))
    assert d.ports["state"].rejected == 1 and not d.sent["torque"]
    d.ports["state"].check = None  # the node's own guard, behind the edge's
    assert d.tick(state=_state(q, 1000))
    tq = d.sent["torque"][-1]
    assert tq.mode == 2 and "non-finite" in tq.status
    assert np.all(np.isfinite(tq.torque))
    d2 = _driver()
    bad = _state(q_stand, 2000)
    bad.q = bad.q[:20]
    bad.num_positions = 20
    assert d2.tick(state=bad)
    tq = d2.sent["torque"][-1]
    assert tq.mode == 2 and np.all(np.isfinite(tq.torque))


def test_unknown_process_parameter_is_a_config_error():
    with pytest.raises(ConfigError) as e:
        build_node(_proc(kp=3), _profile())
    assert e.value.key == "processes.osc.params.kp"


def _ds_plan(node, utime: int):  # type: ignore[no-untyped-def]
    from lcmtypes import mpfc_output_t

    m = node.controller.model
    p = mpfc_output_t()
    p.header.utime = utime
    p.gait_state, p.stance = 2, 0  # double stance after a left touchdown
    p.stance_foot_world = m.foot_center(0).tolist()
    p.next_footstep_world = m.foot_center(1).tolist()
    p.prev_switch_time_s, p.next_switch_time_s = utime * 1e-6, utime * 1e-6 + 0.1
    return p


def _tick_on_plan(d: NodeDriver, q: np.ndarray, utime: int) -> None:
    """A state and a double-stance MPFC plan at ``utime``; no radio command has arrived."""
    assert d.tick(state=_state(q, utime), plan=_ds_plan(d.node, utime))


@pytest.mark.parametrize(("start", "walks"), [("walk", True), ("stand", False)])
def test_before_the_first_command_the_osc_walks_or_stands_as_configured(q_stand, start, walks):
    """The stack walks out of the holder at MPFC's default velocity unless ``start: stand``
    makes the OSC wait for the radio."""
    from processes.osc.controller import STANDING, WALKING

    d = _driver(start=start)
    d.tick(state=_state(q_stand, 1000))  # standing, and the model is updated
    _tick_on_plan(d, q_stand, 1500)
    assert d.node.controller.mode == (WALKING if walks else STANDING)


def test_a_bad_start_value_names_the_key():
    with pytest.raises(ConfigError, match="start"):
        build_node(_proc(start="run"), _profile())


def test_hold_until_plan_sends_zero_torque_off_until_the_first_plan(q_stand):
    """``hold_until_plan``: mode 3 (off), zero torque, while no plan has come (the holder
    keeps the robot); from the first plan on the controller runs."""
    d = _driver(hold_until_plan=True)
    d.tick(state=_state(q_stand, 1000))
    tq = d.sent["torque"][-1]
    assert tq.mode == 3 and tq.torque == (0.0,) * 10 and "waiting" in tq.status
    assert d.node.counters()["mode"] == 3.0
    _tick_on_plan(d, q_stand, 1500)
    tq = d.sent["torque"][-1]
    assert tq.mode in (0, 1) and any(t != 0.0 for t in tq.torque)


def test_a_bad_hold_until_plan_value_names_the_key():
    with pytest.raises(ConfigError, match="hold_until_plan"):
        build_node(_proc(hold_until_plan="yes"), _profile())
    with pytest.raises(ConfigError, match="stand_first_s"):
        build_node(_proc(stand_first_s=-2), _profile())


def test_stand_first_keeps_standing_on_a_walking_plan_then_walks(q_stand):
    """``stand_first_s``: the first controlled ticks stand (in the holder, which the bridge
    releases after standing), whatever the command; then the walking plan is taken up."""
    from processes.osc.controller import STANDING, WALKING

    d = _driver(stand_first_s=0.5)
    d.tick(state=_state(q_stand, 1000))
    _tick_on_plan(d, q_stand, 1500)
    assert d.node.controller.mode == STANDING
    _tick_on_plan(d, q_stand, 501_500)
    assert d.node.controller.mode == WALKING


def test_an_osc_restarted_mid_walk_walks_on_at_once_in_single_stance(q_stand):
    """A restart is not the gantry start: when the first state says the robot is free (the
    holder released), no zero torque and no standing first; the first fresh walking plan is
    taken up in whatever phase (measured live: a restarted OSC that stood first let the
    walking robot fall 1.4 s later)."""
    from processes.osc.controller import WALKING

    d = _driver(hold_until_plan=True, stand_first_s=1.2)
    plan = _ds_plan(d.node, 1000)
    plan.gait_state = 0  # single stance on the left foot, mid-swing
    plan.prev_switch_time_s, plan.next_switch_time_s = 0.0, 0.2
    assert d.tick(state=_state(q_stand, 1000, held=False), plan=plan)
    tq = d.sent["torque"][-1]
    assert d.node.controller.mode == WALKING and tq.mode == 0, tq.status
    assert any(t != 0.0 for t in tq.torque)


def test_soft_start_ramps_the_torques_in_while_the_holder_holds(q_stand):
    """``soft_start_s``: in the holder, the torques of the first controlled ticks are the
    controller's scaled by the time since the first one over ``soft_start_s`` (switched on at
    once against the pinned pelvis, standing bounced both feet off the ground: measured
    live); once the robot is free, or after the ramp, they are the controller's own."""
    soft, plain = _driver(soft_start_s=0.5), _driver()
    for utime, held, scale in ((1_000, True, 0.0), (126_000, True, 0.25),
                               (251_000, True, 0.5), (301_000, False, 1.0),
                               (501_000, True, 1.0), (601_000, True, 1.0)):
        soft.tick(state=_state(q_stand, utime, held))
        plain.tick(state=_state(q_stand, utime, held))
        want = np.asarray(plain.sent["torque"][-1].torque)
        assert np.abs(want).max() > 1.0
        np.testing.assert_allclose(soft.sent["torque"][-1].torque, scale * want, atol=1e-9)


def test_a_bad_soft_start_value_names_the_key():
    with pytest.raises(ConfigError, match="soft_start_s"):
        build_node(_proc(soft_start_s=-1), _profile())
