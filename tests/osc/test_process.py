"""The OSC Node shell: stamps outputs with the state's utime, never publishes a NaN torque."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from lcmtypes import osc_debug_t, robot_state_t, torque_command_t
from runtime.builder import build_node
from runtime.cassie_packets import STATUS_HOLDER_ENGAGED
from runtime.config_types import ProcessConfig, Profile
from runtime.errors import ConfigError

HW = Path(__file__).resolve().parents[2] / "hw_config"


class _Ctx:
    def __init__(self) -> None:
        self.sent: list[tuple[str, object]] = []
        self.now_utime = 0

    def due(self, role: str) -> bool:  # no decimation outside the runners

        return True


    def publish(self, role: str, msg: object) -> None:
        # as on the bus: encode and decode, so nothing is shared with the node
        self.sent.append((role, type(msg).decode(msg.encode())))


class _Inbox:
    def __init__(self, state: robot_state_t) -> None:
        self.state = state

    def latest(self, role: str):
        return self.state if role == "state" else None

    def is_fresh(self, role: str) -> bool:
        return role == "state"

    def trigger(self):
        return self.state


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


def test_node_publishes_torque_and_debug_stamped_with_the_state_utime(q_stand):
    node = build_node(_proc(), _profile())
    ctx = _Ctx()
    node.setup(ctx)
    node.tick(ctx, _Inbox(_state(q_stand, 123_456)))
    roles = dict(ctx.sent)
    tq, dbg = roles["torque"], roles["debug"]
    assert isinstance(tq, torque_command_t) and isinstance(dbg, osc_debug_t)
    assert tq.header.utime == 123_456 and dbg.header.utime == 123_456
    assert tq.num_motors == 10 and tq.mode == 1 and np.all(np.isfinite(tq.torque))
    assert dbg.qp_status == 1 and dbg.num_tasks == len(dbg.task_names) > 0


def test_node_with_nan_or_malformed_state_publishes_finite_safe_torques(q_stand):
    node = build_node(_proc(), _profile())
    ctx = _Ctx()
    node.setup(ctx)
    q = q_stand.copy()
    q[2] = np.nan
    node.tick(ctx, _Inbox(_state(q, 1000)))
    tq = dict(ctx.sent)["torque"]
    assert tq.mode == 2 and "non-finite" in tq.status
    assert np.all(np.isfinite(tq.torque))
    node2 = build_node(_proc(), _profile())
    node2.setup(ctx)
    bad = _state(q_stand, 2000)
    bad.q = bad.q[:20]
    bad.num_positions = 20
    node2.tick(ctx, _Inbox(bad))
    tq = ctx.sent[-2][1]
    assert tq.mode == 2 and np.all(np.isfinite(tq.torque))


def test_unknown_process_parameter_is_a_config_error():
    with pytest.raises(ConfigError) as e:
        build_node(_proc(kp=3), _profile())
    assert e.value.key == "processes.osc.params.kp"


class _PlanInbox(_Inbox):
    """A state and a double-stance MPFC plan; no radio command has arrived."""

    def __init__(self, state: robot_state_t, plan: object) -> None:
        super().__init__(state)
        self.plan = plan

    def latest(self, role: str):
        return {"state": self.state, "plan": self.plan}.get(role)


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


@pytest.mark.parametrize(("start", "walks"), [("walk", True), ("stand", False)])
def test_before_the_first_command_the_osc_walks_or_stands_as_configured(q_stand, start, walks):
    """The stack walks out of the holder at MPFC's default velocity unless ``start: stand``
    makes the OSC wait for the radio."""
    from processes.osc.controller import STANDING, WALKING

    node = build_node(_proc(start=start), _profile())
    ctx = _Ctx()
    node.setup(ctx)
    node.tick(ctx, _Inbox(_state(q_stand, 1000)))  # standing, and the model is updated
    node.tick(ctx, _PlanInbox(_state(q_stand, 1500), _ds_plan(node, 1500)))
    assert node.controller.mode == (WALKING if walks else STANDING)


def test_a_bad_start_value_names_the_key():
    with pytest.raises(ConfigError, match="start"):
        build_node(_proc(start="run"), _profile())


def test_hold_until_plan_sends_zero_torque_off_until_the_first_plan(q_stand):
    """``hold_until_plan``: mode 3 (off), zero torque, while no plan has come (the holder
    keeps the robot); from the first plan on the controller runs."""
    node = build_node(_proc(hold_until_plan=True), _profile())
    ctx = _Ctx()
    node.setup(ctx)
    node.tick(ctx, _Inbox(_state(q_stand, 1000)))
    tq = dict(ctx.sent)["torque"]
    assert tq.mode == 3 and tq.torque == (0.0,) * 10 and "waiting" in tq.status
    assert node.counters()["mode"] == 3.0
    node.tick(ctx, _PlanInbox(_state(q_stand, 1500), _ds_plan(node, 1500)))
    tq = ctx.sent[-2][1] if ctx.sent[-1][0] == "debug" else ctx.sent[-1][1]
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

    node = build_node(_proc(stand_first_s=0.5), _profile())
    ctx = _Ctx()
    node.setup(ctx)
    node.tick(ctx, _Inbox(_state(q_stand, 1000)))
    node.tick(ctx, _PlanInbox(_state(q_stand, 1500), _ds_plan(node, 1500)))
    assert node.controller.mode == STANDING
    node.tick(ctx, _PlanInbox(_state(q_stand, 501_500), _ds_plan(node, 501_500)))
    assert node.controller.mode == WALKING


def test_an_osc_restarted_mid_walk_walks_on_at_once_in_single_stance(q_stand):
    """A restart is not the gantry start: when the first state says the robot is free (the
    holder released), no zero torque and no standing first; the first fresh walking plan is
    taken up in whatever phase (measured live: a restarted OSC that stood first let the
    walking robot fall 1.4 s later)."""
    from processes.osc.controller import WALKING

    node = build_node(_proc(hold_until_plan=True, stand_first_s=1.2), _profile())
    ctx = _Ctx()
    node.setup(ctx)
    plan = _ds_plan(node, 1000)
    plan.gait_state = 0  # single stance on the left foot, mid-swing
    plan.prev_switch_time_s, plan.next_switch_time_s = 0.0, 0.2
    node.tick(ctx, _PlanInbox(_state(q_stand, 1000, held=False), plan))
    tq = ctx.sent[-2][1] if ctx.sent[-1][0] == "debug" else ctx.sent[-1][1]
    assert node.controller.mode == WALKING and tq.mode == 0, tq.status
    assert any(t != 0.0 for t in tq.torque)
