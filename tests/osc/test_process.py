"""The OSC Node shell: stamps outputs with the state's utime, never publishes a NaN torque."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from lcmtypes import osc_debug_t, robot_state_t, torque_command_t
from processes.osc.process import make_node
from runtime.config_types import ProcessConfig, Profile
from runtime.errors import ConfigError

HW = Path(__file__).resolve().parents[2] / "hw_config"


class _Ctx:
    def __init__(self) -> None:
        self.sent: list[tuple[str, object]] = []
        self.now_utime = 0

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
                         source_file=HW / "processes.yaml", params=dict(params))


def _state(q: np.ndarray, utime: int) -> robot_state_t:
    s = robot_state_t()
    s.header.utime = utime
    s.num_positions, s.num_velocities, s.num_motors = 35, 32, 10
    s.q = q.tolist()
    s.v = [0.0] * 32
    s.motor_torque = [0.0] * 10
    return s


def test_node_publishes_torque_and_debug_stamped_with_the_state_utime(q_stand):
    node = make_node(_proc(), _profile())
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
    node = make_node(_proc(), _profile())
    ctx = _Ctx()
    node.setup(ctx)
    q = q_stand.copy()
    q[2] = np.nan
    node.tick(ctx, _Inbox(_state(q, 1000)))
    tq = dict(ctx.sent)["torque"]
    assert tq.mode == 2 and "non-finite" in tq.status
    assert np.all(np.isfinite(tq.torque))
    node2 = make_node(_proc(), _profile())
    node2.setup(ctx)
    bad = _state(q_stand, 2000)
    bad.q = bad.q[:20]
    bad.num_positions = 20
    node2.tick(ctx, _Inbox(bad))
    tq = ctx.sent[-2][1]
    assert tq.mode == 2 and np.all(np.isfinite(tq.torque))


def test_unknown_process_parameter_is_a_config_error():
    with pytest.raises(ConfigError) as e:
        make_node(_proc(kp=3), _profile())
    assert e.value.key == "processes.osc.params.kp"
