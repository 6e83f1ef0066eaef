"""The torque bridge live: LCM state and commands in, real UDP torque packets out."""

from __future__ import annotations

import dataclasses
import socket
import threading
import time

import numpy as np

from lcmtypes import applied_input_t
from processes.torque_bridge.bridge import SOURCE_COMMAND, SOURCE_WATCHDOG_DAMPING
from runtime.builder import build_node
from runtime.bus import Bus
from runtime.cassie_packets import InputPacket
from runtime.loops import LiveRunner
from tests.conftest import wait_for
from tests.state_estimator.scripted import free_udp_port, live_configs
from tests.torque_bridge.support import command, state


def test_live_bridge_sends_one_packet_per_state_acks_it_and_trips_its_watchdog(lcm_url):
    port = free_udp_port()
    rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    rx.bind(("127.0.0.1", port))  # we are the target PC
    rx.settimeout(2.0)
    proc, profile = live_configs(
        "torque_bridge", "processes.torque_bridge.process", lcm_url,
        inputs={"torque": "TEST_TB_TORQUE", "state": "TEST_TB_STATE"},
        outputs={"robot_input": ("udp", port), "applied_input": "TEST_TB_APPLIED"},
    )
    proc = dataclasses.replace(proc, params={"answer_on": "state"})
    node = build_node(proc, profile)
    runner = LiveRunner(node, proc, profile)
    thread = threading.Thread(target=runner.run, daemon=True)
    bus = Bus(lcm_url, source="test")
    applied = bus.subscribe("TEST_TB_APPLIED", applied_input_t, "each", capacity=10000)
    got: list[applied_input_t] = []
    thread.start()
    try:
        time.sleep(0.2)
        tau = np.linspace(-300.0, 300.0, 10)  # some beyond the limits
        pkt = InputPacket()
        sources = []
        for k in range(40):
            t = 500 * k
            if k < 10:
                bus.publish("TEST_TB_TORQUE", command(t, tau))
                time.sleep(0.002)  # the command is there before its state
            bus.publish("TEST_TB_STATE", state(t, motor_vel=1.0, seq=(k + 7) & 0xFF))
            pkt.decode(rx.recv(1024))  # one packet answers each state
            assert pkt.ack == (k + 7) & 0xFF  # ack = the target-PC seq of the state
            assert np.all(np.isfinite(pkt.torque))
            wait_for(lambda k=k: len(got) > k, 2.0, poll=lambda: (bus.drain(0.01), got.extend(
                iter(applied.pop, None))), what="applied_input")
            sources.append(got[k].source)
        limit = np.array(node.params.torque_limit)
        assert sources[:10] == [SOURCE_COMMAND] * 10
        # 10 ms of state time after the last command (utime 4500): damping from utime 14500
        assert sources[10:29] == [SOURCE_COMMAND] * 19
        assert sources[29:] == [SOURCE_WATCHDOG_DAMPING] * 11
        assert got[-1].watchdog_trips == 1
        assert got[9].clamp_count == 10 * int((np.abs(tau) > limit).sum())  # 4 motors, 10 times
        np.testing.assert_allclose(got[5].torque, np.clip(tau, -limit, limit))
        np.testing.assert_allclose(pkt.torque, -np.array(node.params.damping_kd) * 1.0)
    finally:
        runner.stop()
        thread.join(timeout=5)
        rx.close()
        bus.close()


def test_live_bridge_in_real_time_sends_each_command_at_once_and_watches_the_states(lcm_url):
    port = free_udp_port()
    rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    rx.bind(("127.0.0.1", port))
    rx.settimeout(2.0)
    proc, profile = live_configs(
        "torque_bridge", "processes.torque_bridge.process", lcm_url,
        inputs={"torque": "TEST_TB_TORQUE", "state": "TEST_TB_STATE"},
        outputs={"robot_input": ("udp", port), "applied_input": "TEST_TB_APPLIED"},
    )
    node = build_node(proc, profile)  # a real-time profile: answer_on command
    assert node.answer_on == "command"
    runner = LiveRunner(node, proc, profile)
    thread = threading.Thread(target=runner.run, daemon=True)
    bus = Bus(lcm_url, source="test")
    thread.start()
    pkt = InputPacket()
    try:
        time.sleep(0.2)
        for k in range(5):  # the state first (the OSC's input), then its command
            bus.publish("TEST_TB_STATE", state(500 * k, motor_vel=1.0, seq=k))
            t0 = time.monotonic()
            bus.publish("TEST_TB_TORQUE", command(500 * k, [7.0] * 10))
            for _ in range(5):  # (a watchdog tick may answer the state before the command)
                pkt.decode(rx.recv(1024))
                if pkt.torque[0] == 7.0:
                    break
            assert time.monotonic() - t0 < 0.5  # sent on the command, not on a later state
            assert pkt.ack == k and np.allclose(pkt.torque, 7.0)
        # no more commands: each new state is answered by the watchdog ticks, with the last
        # command for 10 ms of state time, then with damping
        torques = []
        for k in range(5, 40):
            bus.publish("TEST_TB_STATE", state(500 * k, motor_vel=1.0, seq=k))
            pkt.decode(rx.recv(1024))
            assert pkt.ack == k
            torques.append(pkt.torque[0])
        assert torques[0] == 7.0 and torques[-1] == -5.0  # hip roll kd 5 at 1 rad/s
        assert node.bridge.watchdog_trips == 1
    finally:
        runner.stop()
        thread.join(timeout=5)
        rx.close()
        bus.close()
