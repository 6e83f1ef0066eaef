"""``params.release_after_s``: the bridge sets the holder's release flag only once the
controller has stood (or walked) without a break for that long, as an operator lowers the
robot from its gantry once the controller holds it; off or safe mode starts the count again."""

from __future__ import annotations

import pytest

from processes.torque_bridge.process import TorqueBridgeNode
from runtime.builder import build_node
from runtime.cassie_packets import FLAG_RELEASE_HOLDER
from runtime.config import load_profile
from runtime.driver import NodeDriver
from runtime.errors import ConfigError
from tests.torque_bridge.support import command, packets, state


def _send(d: NodeDriver, k: int, mode: int) -> int:
    """A state and the 1 kHz controller's command for it, in ``mode``; the release flag of
    the packet the command sent."""
    u = 1000 * k
    c = command(u, [1.0] * 10, seq=2 * k)
    c.mode = mode
    assert d.tick(state=state(u, seq=2 * k), torque=c)
    (p,) = packets(d)
    d.sent["robot_input"].clear()
    return p.flags & FLAG_RELEASE_HOLDER


def test_release_flag_after_one_second_of_standing_and_not_before():
    node = TorqueBridgeNode(answer_on="command")
    node.release_after_us = 1_000_000
    d = NodeDriver(node, output_rate_hz={"applied_input": 200.0})  # as hw_config decimates it
    flags = [_send(d, k, mode=3) for k in range(1, 501)]  # 0.5 s off (zero torque, no plan)
    # 0.8 s standing, then a safe-mode blip: the count restarts
    flags += [_send(d, k, mode=1) for k in range(501, 1301)]
    flags.append(_send(d, 1301, mode=2))
    flags += [_send(d, k, mode=1) for k in range(1302, 2302)]  # 1 s of standing: released
    assert not any(flags)
    assert _send(d, 2302, mode=0) == FLAG_RELEASE_HOLDER  # at its end
    assert _send(d, 2303, mode=0) == FLAG_RELEASE_HOLDER  # and it stays set


def test_sim_profile_stands_in_the_holder_before_release(tmp_path):
    prof = load_profile("hw_config/sim.yaml")
    node = build_node(prof.processes["torque_bridge"], prof)
    assert node.release_after_us == 1_000_000
    assert prof.processes["sim"].params["holder_release"] == "manual"
    assert prof.processes["osc"].params["hold_until_plan"] is True


@pytest.mark.parametrize("value", [-1.0, "soon", True, 120.0])
def test_a_bad_release_after_is_a_config_error_naming_the_key(value):
    prof = load_profile("hw_config/sim.yaml")
    proc = prof.processes["torque_bridge"]
    proc.params["release_after_s"] = value
    with pytest.raises(ConfigError, match="release_after_s"):
        build_node(proc, prof)
