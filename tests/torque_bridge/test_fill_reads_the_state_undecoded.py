"""A fill (a state the 1 kHz OSC skips, answered with the newest torque) reads only the
state's utime and packet seq from its bytes: no decode, and the same packet as with one; a
state whose utime does not follow on is decoded and checked as any input is, and so is one
state in every 0.1 s, which keeps the edge check's clock in step with the stream."""

from __future__ import annotations

import numpy as np

from lcmtypes import robot_state_t
from processes.torque_bridge.process import TorqueBridgeNode
from runtime.codecs import raw_utime_and_seq
from runtime.driver import NodeDriver
from tests.torque_bridge.support import command, packets, state


def test_raw_utime_and_seq_agree_with_the_decoded_state_whatever_its_lengths():
    for nq, nv, source, seq in ((35, 32, "state_estimator", 7), (0, 0, "", 255),
                                (3, 1, "x" * 60, 300), (35, 32, "e", -1)):
        s = robot_state_t()
        s.header.utime, s.header.source = 123_456_789_012, source
        s.num_positions, s.num_velocities, s.num_motors = nq, nv, 2
        s.q, s.v, s.motor_torque = [1.5] * nq, [2.5] * nv, [0.5, 0.25]
        s.packet_seq, s.packets_lost, s.packets_rejected = seq, 2**40 + 3, 2**33
        got = raw_utime_and_seq(s.encode())
        assert got == (123_456_789_012, seq & 0xFF)
    assert raw_utime_and_seq(b"\0" * 20) is None


def _rig(limits: dict | None = None) -> NodeDriver:
    """The bridge filling in a 1 kHz OSC's skipped states (``fill_hz``), driven by hand."""
    return NodeDriver(TorqueBridgeNode(answer_on="command", fill_hz=1000.0), limits=limits)


def test_a_fill_acks_the_new_state_without_decoding_it():
    d = _rig()
    st = d.ports["state"]
    # the OSC's torque for state 1000
    assert d.tick(state=state(1000, seq=2), torque=command(1000, [3.0] * 10, seq=2))
    for k in range(3, 13):  # the odd states, each filled in with the same torque
        d.put("state", state(500 * k, seq=k))
        decoded_before = st.peek()
        assert d.fill_tick()
        assert not st.fresh  # (the runner marks a filled state answered)
        sent = packets(d)
        assert sent[-1].ack == k and np.allclose(sent[-1].torque, 3.0)
        if k > 3:  # (the first is decoded and checked: one in every 0.1 s is)
            assert st.peek() is decoded_before  # read from its bytes, never decoded
    assert d.node.fills == 10 and len(d.sent["robot_input"]) == 11
    # the fallback (no command for the watchdog's 10 ms) reads the newest state in full
    assert d.inbox.latest("state").header.utime == 6000


def test_a_state_far_ahead_of_the_last_answer_is_decoded_and_checked():
    d = _rig()
    st = d.ports["state"]
    st.check = lambda m: "utime off its clock" if m.header.utime > 10**9 else None
    assert d.tick(torque=command(1000, [3.0] * 10, seq=2))
    assert d.fill_tick(state=state(10**12, seq=9))  # a corrupt utime: rejected at the edge,
    assert st.rejected == 1 and len(d.sent["robot_input"]) == 1  # not answered
    assert d.fill_tick(state=state(1500, seq=3))
    assert len(d.sent["robot_input"]) == 2 and packets(d)[-1].ack == 3


def test_a_second_of_fills_keeps_the_edge_checks_clock_in_step():
    """A 1 kHz OSC's torques and the fills between them, with no state decoded on the way
    (a command carries its state's ack): the one state decoded in every 0.1 s keeps
    ``utime_step_s`` following the stream, so a state decoded after 1.5 s is admitted, not
    rejected as off its clock (measured live before: after a bridge's take-over it was, the
    bridge fell back to damping, and Cassie fell)."""
    d = _rig(limits={"state": {"utime_step_s": (0.0, 1.0)}})
    st = d.ports["state"]
    for k in range(2, 3002):  # 1.5 s of states at 2 kHz
        d.put("state", state(500 * k, seq=k & 0xFF))
        if k % 2 == 0:  # the OSC's torque for this state, or else a fill
            assert d.tick(torque=command(500 * k, [3.0] * 10, seq=k & 0xFF))
        else:
            assert d.fill_tick()
    assert d.node.fills == 1500 and len(d.sent["robot_input"]) == 3000 and st.rejected == 0
    d.put("state", state(500 * 3002, seq=3002 & 0xFF))
    assert d.inbox.latest("state").header.utime == 500 * 3002  # admitted: in step
    assert st.rejected == 0
