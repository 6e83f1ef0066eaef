"""The estimator node's message contract: stamps, sizes, status packing, duplicates, restarts."""

from __future__ import annotations

import numpy as np

from processes.state_estimator.estimator import RESTART_AFTER, STATUS_INITIALIZING
from processes.state_estimator.process import StateEstimatorNode
from runtime.cassie_packets import STATUS_HOLDER_ENGAGED
from runtime.codecs import packet_seq_of
from runtime.harness import Binding, Harness
from tests.state_estimator.scripted import sim_settings


def _rig() -> tuple[StateEstimatorNode, Harness, list, list]:
    node = StateEstimatorNode()
    h = Harness([Binding(node, inputs={"robot_output": "OUT"},
                         outputs={"state": "S", "network_state": "N", "contact": "C"})])
    states: list = []
    contacts: list = []
    h.tap("S", lambda _t, m: states.append(m))
    h.tap("C", lambda _t, m: contacts.append(m))
    return node, h, states, contacts


def _packets(n: int, start_seq: int = 0) -> list[bytes]:
    from sim.target_pc import TargetPC, make_core

    core = make_core(config=sim_settings(0.02).sim)
    tpc = TargetPC(core)
    for _ in range(start_seq):
        tpc.link.next_seq()
    return [bytes(tpc.realtime_cycle(None)) for _ in range(n)]


def test_state_is_stamped_with_packet_time_and_carries_seq_and_target_status():
    _, h, states, contacts = _rig()
    pkts = _packets(30, start_seq=250)  # seq wraps 255 -> 0 inside the run
    for i, raw in enumerate(pkts):
        h.inject("OUT", raw, at_us=1000 * i)
    h.run_until(10**6)
    assert len(states) == len(pkts) == len(contacts)
    for i, s in enumerate(states):
        assert s.header.utime == 500 * (i + 1)  # the sim's utime, not the harness clock
        assert contacts[i].header.utime == s.header.utime
        assert packet_seq_of(s) == (250 + i) & 0xFF
        assert s.target_status & STATUS_HOLDER_ENGAGED  # the target PC's status bits
        assert len(s.q) == 35 and len(s.v) == 32 and len(s.motor_torque) == 10
        assert abs(np.linalg.norm(s.q[3:7]) - 1.0) < 1e-9
    assert states[0].status & STATUS_INITIALIZING
    assert states[-1].packets_lost == 0 and states[-1].packets_rejected == 0


def test_a_resent_packet_is_answered_again_not_rejected():
    node, h, states, _ = _rig()
    pkts = _packets(5)
    for i, raw in enumerate([*pkts[:3], pkts[2], *pkts[3:]]):
        h.inject("OUT", raw, at_us=1000 * i)
    h.run_until(10**6)
    assert [s.header.utime for s in states] == [500, 1000, 1500, 1500, 2000, 2500]
    assert node.rejected == 0 and node.link.duplicates == 1 and node.link.lost == 0


def test_a_resend_after_garbage_is_still_answered_as_the_same_state():
    from runtime.cassie_packets import OUTPUT_SIZE

    node, h, states, _ = _rig()
    pkts = _packets(5)
    # lockstep: the answer to the 3rd state was lost, a zero-filled datagram came in between,
    # and the sim resent its 3rd packet (twice) before it got its answer and went on
    for i, raw in enumerate([*pkts[:3], bytes(OUTPUT_SIZE), pkts[2], pkts[2], *pkts[3:]]):
        h.inject("OUT", raw, at_us=1000 * i)
    h.run_until(10**6)
    assert [s.header.utime for s in states] == [500, 1000, 1500, 1500, 1500, 2000, 2500]
    assert node.rejected == 1 and node.link.duplicates == 2


def test_a_restarted_target_pc_reinitialises_the_estimator():
    node, h, states, _ = _rig()
    first = _packets(300)
    again = _packets(RESTART_AFTER + 50)  # a new sim: time starts over
    for i, raw in enumerate(first + again):
        h.inject("OUT", raw, at_us=1000 * i)
    h.run_until(10**7)
    assert node.estimator is not None and node.estimator.restarts == 1
    assert node.rejected == RESTART_AFTER - 1  # the 200th stale packet restarts, accepted
    assert states[-1].header.utime == 500 * len(again)
    assert abs(states[-1].q[2] - 0.95) < 0.02  # re-initialised on the feet, not dead-reckoned


def test_a_successor_carries_on_from_the_saved_state_or_starts_afresh_when_it_is_old(tmp_path):
    """A killed estimator's standby loads its predecessor's state (runtime.checkpoint) and
    publishes exactly what the predecessor would have; a state 75 ms older than the first
    packet (over MAX_CARRY_OVER_US) is no longer that robot's: it starts afresh."""
    from runtime.checkpoint import StateCheckpoint

    pkts = _packets(400)
    first, h1, states1, _ = _rig()
    for i, raw in enumerate(pkts[:200]):
        h1.inject("OUT", raw, at_us=1000 * i)
    h1.run_until(200_000)
    path = tmp_path / "est.state"
    StateCheckpoint(path, first.state_arrays()).save()
    for i, raw in enumerate(pkts[200:300]):
        h1.inject("OUT", raw, at_us=200_000 + 1000 * i)
    h1.run_until(10**6)

    second, h2, states2, _ = _rig()
    h2.run_until(1)  # set up
    assert StateCheckpoint(path, second.state_arrays()).load()
    second.restored()
    for i, raw in enumerate(pkts[200:300]):
        h2.inject("OUT", raw, at_us=1000 * i)
    h2.run_until(10**6)
    assert len(states2) == 100
    for a, b in zip(states1[200:300], states2, strict=True):
        assert a.header.utime == b.header.utime and a.q == b.q and a.v == b.v
        assert a.status == b.status and a.alip_x == b.alip_x

    late, h3, states3, _ = _rig()
    h3.run_until(1)
    StateCheckpoint(path, late.state_arrays()).load()
    late.restored()
    for i, raw in enumerate(pkts[350:]):  # 75 ms of packets missed
        h3.inject("OUT", raw, at_us=1000 * i)
    h3.run_until(10**6)
    assert states3[0].status & STATUS_INITIALIZING
