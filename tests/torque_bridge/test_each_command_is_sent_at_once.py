"""Real time (answer_on command): each torque command goes out at once, answering the newest
state; when commands stop, the watchdog ticks answer the new states with the fallback once no
fresh command is left."""

from __future__ import annotations

import numpy as np

from processes.torque_bridge.process import TorqueBridgeNode
from runtime.cassie_packets import InputPacket
from tests.torque_bridge.support import command, state
from tools.benchmarks.common import DirectInbox


class _Ctx:
    def __init__(self) -> None:
        self.now_utime = 0
        self.sent: list[InputPacket] = []

    def due(self, role: str) -> bool:
        return True

    def publish(self, role: str, msg: object) -> None:
        if role == "robot_input":
            p = InputPacket()
            p.decode(msg)  # type: ignore[arg-type]
            self.sent.append(p)


def test_each_command_is_one_packet_and_silence_falls_back_after_the_watchdog():
    node = TorqueBridgeNode(answer_on="command")
    ctx, inbox = _Ctx(), DirectInbox("torque")
    node.setup(ctx)
    for k in range(1, 11):  # a command per state, as the OSC at 2 kHz sends
        u = 500 * k
        inbox.messages["state"] = state(u, motor_vel=1.0, seq=k)
        inbox.messages["torque"] = command(u, [float(k)] * 10)
        node.tick(ctx, inbox)
        assert len(ctx.sent) == k
        assert ctx.sent[-1].ack == k and np.allclose(ctx.sent[-1].torque, float(k))
    # the controller stops; states go on; the runner's watchdog ticks carry no trigger
    inbox.messages["torque"] = None
    sources = []
    for k in range(11, 11 + 40):
        inbox.messages["state"] = state(500 * k, motor_vel=1.0, seq=k)
        node.tick(ctx, inbox)  # one new state each: answered
        node.tick(ctx, inbox)  # no new state: nothing to answer
        sources.append(node.bridge.source)
    assert len(ctx.sent) == 10 + 40
    # the last command stays in force for the 10 ms watchdog, then damping (-kd * velocity)
    fresh = [s == 0 for s in sources]
    assert all(fresh[:19]) and not any(fresh[21:])
    assert np.allclose(ctx.sent[-1].torque[:4], -5.0)  # hip/knee kd 5 at 1 rad/s
    assert node.bridge.watchdog_trips == 1
