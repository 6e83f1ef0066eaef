"""The estimator process, live (LiveRunner, real UDP in, real LCM out), fed by the real sim."""

from __future__ import annotations

import socket
import threading
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

from lcmtypes import contact_t, robot_state_t
from runtime.builder import build_node
from runtime.bus import Bus
from runtime.cassie_packets import OutputPacket, encode_input
from runtime.loops import LiveRunner
from tests.conftest import wait_for
from tests.state_estimator.scripted import free_udp_port, live_configs, pd_torque, sim_settings


class LiveEstimator:
    """The estimator node in a LiveRunner thread; the test is the target PC and the listener."""

    def __init__(self, lcm_url: str) -> None:
        self.port = free_udp_port()
        proc, profile = live_configs(
            "state_estimator", "processes.state_estimator.process", lcm_url,
            inputs={"robot_output": ("udp", self.port)},
            outputs={"state": "TEST_SE_STATE", "network_state": "NETWORK_TEST_SE_STATE",
                     "contact": "TEST_SE_CONTACT"},
        )
        self.node = build_node(proc, profile)
        self.runner = LiveRunner(self.node, proc, profile)
        self.bus = Bus(lcm_url, source="test")
        self.states = self.bus.subscribe("TEST_SE_STATE", robot_state_t, "each", capacity=100000)
        self.network = self.bus.subscribe("NETWORK_TEST_SE_STATE", robot_state_t, "each",
                                          capacity=100000)
        self.contact = self.bus.subscribe("TEST_SE_CONTACT", contact_t, "each", capacity=100000)
        self.got: list[Any] = []
        self.net: list[Any] = []
        self.thread = threading.Thread(target=self.runner.run, daemon=True)
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)

    def start(self) -> None:
        self.thread.start()

    def send(self, data: bytes) -> None:
        self.sock.sendto(data, ("127.0.0.1", self.port))

    def poll(self) -> None:
        self.bus.drain(0.005)
        while (m := self.states.pop()) is not None:
            self.got.append(m)
        while (m := self.network.pop()) is not None:
            self.net.append(m)

    def wait_for_states(self, n: int, timeout: float = 10.0) -> None:
        wait_for(lambda: len(self.got) >= n, timeout, poll=self.poll, what=f"{n} states")

    def close(self) -> None:
        self.runner.stop()
        self.thread.join(timeout=5)
        self.sock.close()
        self.bus.close()


@pytest.fixture
def live(lcm_url: str) -> Iterator[LiveEstimator]:
    le = LiveEstimator(lcm_url)
    le.start()
    yield le
    le.close()


def _sim(holder_timeconst_s: float = 0.2) -> Any:
    from sim.target_pc import TargetPC, make_core

    core = make_core(config=sim_settings(holder_timeconst_s).sim)
    return core, TargetPC(core)


def test_standing_still_velocity_stays_near_zero_and_height_near_truth(live: LiveEstimator):
    core, tpc = _sim()
    q0 = core.q_start[core.idx.motor_qpos].copy()
    truth: dict[int, tuple[np.ndarray, np.ndarray]] = {}
    n = 4000  # 2 s of sim, in bursts, paced by the estimator's answers
    cmd = None
    for k in range(n):
        d = core.d
        tau = pd_torque("still", core.time, q0, d.qpos[core.idx.motor_qpos],
                        d.qvel[core.idx.motor_dof])
        cmd = encode_input(k, tpc.link.own_seq, tau)
        live.send(bytes(tpc.realtime_cycle(cmd)))
        truth[core.utime] = (d.qpos[0:3].copy(), d.qvel[0:3].copy())
        if k % 25 == 24:
            live.wait_for_states(k + 1)
    live.wait_for_states(n)
    assert len(live.got) == n
    assert [m.header.utime for m in live.got] == sorted(truth)  # every packet, in order
    assert live.got[-1].packets_lost == 0 and live.got[-1].packets_rejected == 0
    # NETWORK_ copy: every 10th state (2 kHz -> 200 Hz)
    live.poll()
    assert len(live.net) == n // 10
    after = [m for m in live.got if m.header.utime >= 700_000]  # settled on the soft holder
    v = np.array([m.v[0:3] for m in after])
    z_est = np.array([m.q[2] for m in after])
    z_true = np.array([truth[m.header.utime][0][2] for m in after])
    v_true = np.array([truth[m.header.utime][1] for m in after])
    assert np.abs(v_true).max() < 0.02  # the robot really is standing still
    assert np.abs(v).max() < 0.03, np.abs(v).max(axis=0)
    assert np.sqrt((v**2).mean()) < 0.01
    assert np.abs(z_est - z_true).max() < 0.01
    # the contact-aided correction is active (the soft holder unloads one foot below the
    # 90 N contact threshold at times, so "both" is not guaranteed)
    assert all(m.in_contact[0] or m.in_contact[1] for m in after)
    assert all(m.alip_stance in (0, 1) for m in after)


def test_lost_and_bad_packets_over_udp_are_counted_and_never_passed_on(live: LiveEstimator):
    core, tpc = _sim()
    sent_utimes = []
    skipped = {50, 51, 52, 120}
    bad_at = {80, 150}
    for k in range(200):
        raw = bytearray(tpc.realtime_cycle(None))
        if k in skipped:
            continue  # lost on the wire: a gap in seq
        if k in bad_at:
            pkt = OutputPacket()
            pkt.decode(bytes(raw))
            if k == 80:
                pkt.joint_vel[3] = float("nan")  # NaN: rejected by the packet decoder
            else:
                pkt.imu_quat[:] = (2.0, 0.0, 0.0, 0.0)  # not a rotation: range check
            raw = bytearray(pkt.to_bytes(pkt.seq, pkt.ack))
        else:
            sent_utimes.append(core.utime)
        live.send(bytes(raw))
        if k % 20 == 19:
            live.wait_for_states(len(sent_utimes))
    live.send(b"\x00" * 10)  # wrong size
    live.send(bytes(tpc.realtime_cycle(None)))
    sent_utimes.append(core.utime)
    live.wait_for_states(len(sent_utimes))
    got = [m.header.utime for m in live.got]
    assert got == sent_utimes  # bad ones never published
    last = live.got[-1]
    assert last.packets_rejected == 3
    # the skipped packets, and the rejected ones (their seq never reached the link counter)
    assert last.packets_lost == len(skipped) + len(bad_at)
    assert "rejected 3" in live.node.status()
