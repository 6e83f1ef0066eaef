"""``params.release_after_s``: the bridge sets the holder's release flag only once the
controller has stood (or walked) without a break for that long, as an operator lowers the
robot from its gantry once the controller holds it; off or safe mode starts the count again."""

from __future__ import annotations

import pytest

from processes.torque_bridge.process import TorqueBridgeNode
from runtime.builder import build_node
from runtime.cassie_packets import FLAG_RELEASE_HOLDER, InputPacket
from runtime.config import load_profile
from runtime.errors import ConfigError
from tests.torque_bridge.support import command, state
from tools.benchmarks.common import DirectInbox


class _Ctx:
    def __init__(self) -> None:
        self.now_utime = 0
        self.flags: list[int] = []

    def due(self, role: str) -> bool:
        return False

    def publish(self, role: str, msg: object) -> None:
        p = InputPacket()
        p.decode(msg)  # type: ignore[arg-type]
        self.flags.append(p.flags & FLAG_RELEASE_HOLDER)


def _send(node: TorqueBridgeNode, ctx: _Ctx, inbox: DirectInbox, k: int, mode: int) -> None:
    u = 1000 * k  # a 1 kHz controller
    inbox.messages["state"] = state(u, seq=2 * k)
    c = command(u, [1.0] * 10, seq=2 * k)
    c.mode = mode
    inbox.messages["torque"] = c
    node.tick(ctx, inbox)


def test_release_flag_after_one_second_of_standing_and_not_before():
    node = TorqueBridgeNode(answer_on="command")
    node.release_after_us = 1_000_000
    ctx, inbox = _Ctx(), DirectInbox("torque")
    node.setup(ctx)
    for k in range(1, 501):  # 0.5 s off (zero torque, waiting for a plan)
        _send(node, ctx, inbox, k, mode=3)
    for k in range(501, 1301):  # 0.8 s standing, then a safe-mode blip: the count restarts
        _send(node, ctx, inbox, k, mode=1)
    _send(node, ctx, inbox, 1301, mode=2)
    for k in range(1302, 2302):  # 1 s of standing: released at its end
        _send(node, ctx, inbox, k, mode=1)
    assert not any(ctx.flags[:2301])
    _send(node, ctx, inbox, 2302, mode=0)
    assert ctx.flags[-1] == FLAG_RELEASE_HOLDER
    _send(node, ctx, inbox, 2303, mode=0)
    assert ctx.flags[-1] == FLAG_RELEASE_HOLDER  # and it stays set


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
