"""Lockstep (answer_on torque): the bridge answers a state only once the controller's torque
for that state has arrived, and sends the torque of the state before (the 2 kHz cycle's
one-tick latency, made exact), so the sim never steps ahead of the controller."""

from __future__ import annotations

import numpy as np
import pytest

from processes.torque_bridge.process import TorqueBridgeNode
from runtime.builder import build_node
from runtime.config import HW_CONFIG_DIR, load_profile
from runtime.errors import ConfigError
from runtime.harness import Binding, Harness

from .support import command, state


def _rig() -> tuple[Harness, list[tuple[int, np.ndarray]]]:
    from runtime.cassie_packets import InputPacket

    node = TorqueBridgeNode(answer_on="torque")
    h = Harness([Binding(node, inputs={"torque": "CMD", "state": "STATE"},
                         outputs={"robot_input": "UDP", "applied_input": "APPLIED"})])
    sent: list[tuple[int, np.ndarray]] = []

    def on_packet(_t: int, raw: bytes) -> None:
        p = InputPacket()
        p.decode(raw)
        sent.append((p.ack, p.torque.copy()))

    h.tap("UDP", on_packet)
    return h, sent


def test_a_state_is_answered_only_by_its_own_torque_with_the_previous_command():
    h, sent = _rig()
    for k in range(1, 5):
        t = 500 * k
        h.inject("STATE", state(t, seq=k), at_us=t)
        h.run_until(t)
        assert len(sent) == k - 1  # the state alone is not answered
        h.inject("CMD", command(t - 1, [9.0] * 10), at_us=t)  # an older state's torque
        h.run_until(t)
        assert len(sent) == k - 1
        h.inject("CMD", command(t, [float(k)] * 10), at_us=t)
        h.run_until(t)
        assert len(sent) == k
        ack, tau = sent[-1]
        assert ack == k
        # the first answer has no earlier torque (zero); then each carries the previous one
        assert np.allclose(tau, 0.0 if k == 1 else float(k - 1))


def test_auto_answers_each_command_in_real_time_and_each_torque_in_lockstep():
    sim = load_profile(HW_CONFIG_DIR / "sim.yaml")
    node = build_node(sim.processes["torque_bridge"], sim)
    assert node.answer_on == "command" and node.trigger_role == "torque"
    assert node.trigger_timeout_s is not None  # the watchdog ticks when commands stop
    exp = load_profile(HW_CONFIG_DIR / "experiment.yaml")
    assert build_node(exp.processes["torque_bridge"], exp).trigger_role == "torque"


def test_a_bad_answer_on_value_names_the_key():
    import dataclasses

    sim = load_profile(HW_CONFIG_DIR / "sim.yaml")
    proc = dataclasses.replace(sim.processes["torque_bridge"], params={"answer_on": "never"})
    with pytest.raises(ConfigError, match="answer_on"):
        build_node(proc, sim)
