"""Real time (answer_on command): each torque command goes out at once, answering the newest
state; when commands stop, the watchdog ticks answer the new states with the fallback once no
fresh command is left."""

from __future__ import annotations

import numpy as np

from processes.torque_bridge.process import TorqueBridgeNode
from runtime.driver import NodeDriver
from tests.torque_bridge.support import command, packets, state


def test_each_command_is_one_packet_and_silence_falls_back_after_the_watchdog():
    d = NodeDriver(TorqueBridgeNode(answer_on="command"))
    node = d.node
    for k in range(1, 11):  # a command per state, as the OSC at 2 kHz sends
        u = 500 * k
        assert d.tick(state=state(u, motor_vel=1.0, seq=k), torque=command(u, [float(k)] * 10))
        sent = packets(d)
        assert len(sent) == k
        assert sent[-1].ack == k and np.allclose(sent[-1].torque, float(k))
    # the controller stops; states go on; the runner's watchdog ticks carry no trigger
    assert not d.tick()
    sources = []
    for k in range(11, 11 + 40):
        d.timeout_tick(state=state(500 * k, motor_vel=1.0, seq=k))  # a new state: answered
        d.timeout_tick()  # no new state: nothing to answer
        sources.append(node.bridge.source)
    sent = packets(d)
    assert len(sent) == 10 + 40
    # the last command stays in force for the 10 ms watchdog, then damping (-kd * velocity)
    fresh = [s == 0 for s in sources]
    assert all(fresh[:19]) and not any(fresh[21:])
    assert np.allclose(sent[-1].torque[:4], -5.0)  # hip/knee kd 5 at 1 rad/s
    assert node.bridge.watchdog_trips == 1
