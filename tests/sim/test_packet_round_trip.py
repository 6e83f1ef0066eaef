"""The UDP packets survive a real socket round trip bit for bit, and both ends' counters see
loss and round-trip delay, across the 8-bit sequence wraparound."""

from __future__ import annotations

import re
import socket

import numpy as np

from runtime.cassie_packets import (
    INPUT_LAYOUT,
    INPUT_SIZE,
    OUTPUT_LAYOUT,
    OUTPUT_SIZE,
    STATUS_HOLDER_ENGAGED,
    InputPacket,
    LinkCounter,
    OutputPacket,
)
from sim.target_pc import TargetPC, make_core
from sim.terrain import flat

from .conftest import REPO


def _udp_pair() -> tuple[socket.socket, socket.socket]:
    a = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    b = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    a.bind(("127.0.0.1", 0))
    b.bind(("127.0.0.1", 0))
    a.settimeout(2.0)
    b.settimeout(2.0)
    a.connect(b.getsockname())
    b.connect(a.getsockname())
    return a, b


def test_state_and_torque_packets_round_trip_over_udp() -> None:
    tpc = TargetPC(make_core(flat()), "realtime")
    sim_sock, nuc_sock = _udp_pair()
    try:
        nuc_link = LinkCounter()
        rx_state = OutputPacket()
        tx_torque = InputPacket()
        rng = np.random.default_rng(1)
        pending: bytes | None = None
        torque = np.zeros(10)
        for k in range(6):
            state = bytes(tpc.realtime_cycle(pending))  # the target PC takes the torque packet
            if pending is not None:
                np.testing.assert_array_equal(tpc.inp.torque, torque)
                assert tpc.inp.ack == rx_state.seq  # it answered the previous state
            sim_sock.send(state)
            got = nuc_sock.recv(2048)
            assert got == state
            rx_state.decode(got)
            nuc_link.on_receive(rx_state.seq, rx_state.ack)
            assert rx_state.utime == tpc.core.utime
            d, idx = tpc.core.d, tpc.core.idx
            np.testing.assert_array_equal(rx_state.motor_pos, d.qpos[idx.motor_qpos])
            np.testing.assert_array_equal(rx_state.imu_quat, d.qpos[3:7])
            np.testing.assert_array_equal(rx_state.joint_vel, d.qvel[idx.joint_dof])
            # the first non-zero torque releases the start-up holder
            assert bool(rx_state.status & STATUS_HOLDER_ENGAGED) == (k == 0)
            torque = rng.uniform(-1.0, 1.0, 10)
            tx_torque.torque[:] = torque
            nuc_sock.send(tx_torque.encode(nuc_link.next_seq(), nuc_link.last_peer_seq))
            pending = sim_sock.recv(2048)
            assert len(pending) == INPUT_SIZE
        assert tpc.link.lost == 0 and nuc_link.lost == 0
        assert tpc.link.received == 5 and nuc_link.received == 6
        assert tpc.link.round_trip_cycles == 0  # each answer came before the next state left
    finally:
        sim_sock.close()
        nuc_sock.close()


def test_link_counter_counts_loss_and_round_trip_across_wraparound() -> None:
    a, b = LinkCounter(), LinkCounter()
    dropped_a_to_b = {5, 6, 300, 301, 302, 511}
    lag = 3  # b answers the packet a sent `lag` cycles ago
    sent_by_a: list[tuple[int, int]] = []
    for k in range(600):
        sent_by_a.append((a.next_seq(), a.last_peer_seq))
        if k not in dropped_a_to_b:
            b.on_receive(*sent_by_a[-1])
        if k >= lag:
            seq_b = b.next_seq()
            a.on_receive(seq_b, sent_by_a[k - lag][0])
    assert b.lost == len(dropped_a_to_b)  # every gap counted, through seq 255 -> 0
    assert a.lost == 0
    assert a.round_trip_cycles == lag
    b.on_receive(b.last_peer_seq, 0)  # a retransmit
    assert b.duplicates == 1
    b.on_receive((b.last_peer_seq + 200) & 0xFF, 0)  # an outage of 199: ambiguous mod 256
    assert b.resyncs == 1 and b.lost == len(dropped_a_to_b)
    b.on_receive((b.last_peer_seq + 2) & 0xFF, 0)  # counting goes on from there
    assert b.lost == len(dropped_a_to_b) + 1


def test_documented_layout_matches_the_code() -> None:
    doc = (REPO / "docs" / "udp_protocol.md").read_text(encoding="utf-8")
    assert OUTPUT_SIZE == 476 and INPUT_SIZE == 92
    for layout in (OUTPUT_LAYOUT, INPUT_LAYOUT):
        for name in layout.names:
            offset = layout.fields[name][1]
            assert re.search(rf"\|\s*{offset}\s*\|\s*\d+\s*\|[^|]*\|\s*`{name}`", doc), (
                f"docs/udp_protocol.md has no row for {name} at offset {offset}")
