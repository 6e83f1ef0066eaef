"""A fill (a state the 1 kHz OSC skips, answered with the newest torque) reads only the
state's utime and packet seq from its bytes: no decode, and the same packet as with one; a
state whose utime does not follow on is decoded and checked as any input is, and so is one
state in every 0.1 s, which keeps the edge check's clock in step with the stream."""

from __future__ import annotations

import numpy as np

from lcmtypes import robot_state_t
from processes.state_estimator.process import raw_utime_and_seq
from processes.torque_bridge.process import TorqueBridgeNode
from runtime.bus import Subscription
from runtime.cassie_packets import InputPacket
from runtime.port_buffer import PortInbox
from tests.torque_bridge.support import command, state


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


def _rig() -> tuple[TorqueBridgeNode, _Ctx, dict[str, Subscription], PortInbox]:
    node = TorqueBridgeNode(answer_on="command", fill_hz=1000.0)
    ports = {"torque": Subscription("OSC_TORQUE", type(command(0, [0.0])), "newest", 1),
             "state": Subscription("CASSIE_STATE", robot_state_t, "newest", 1)}
    ctx = _Ctx()
    node.setup(ctx)
    return node, ctx, ports, PortInbox(ports)


def test_a_fill_acks_the_new_state_without_decoding_it():
    node, ctx, ports, inbox = _rig()
    st = ports["state"]
    st._on_message("CASSIE_STATE", state(1000, seq=2).encode())
    inbox._trigger = command(1000, [3.0] * 10, seq=2)  # the OSC's torque for state 1000
    node.tick(ctx, inbox)
    inbox._trigger = None
    for k in range(3, 13):  # the odd states, each filled in with the same torque
        st._on_message("CASSIE_STATE", state(500 * k, seq=k).encode())
        decoded_before = st.peek()
        node.tick(ctx, inbox)
        st.fresh = False  # (the runner marks a filled state answered)
        assert ctx.sent[-1].ack == k and np.allclose(ctx.sent[-1].torque, 3.0)
        if k > 3:  # (the first is decoded and checked: one in every 0.1 s is)
            assert st.peek() is decoded_before  # read from its bytes, never decoded
    assert node.fills == 10 and len(ctx.sent) == 11
    # the fallback (no command for the watchdog's 10 ms) reads the newest state in full
    assert inbox.latest("state").header.utime == 6000


def test_a_state_far_ahead_of_the_last_answer_is_decoded_and_checked():
    node, ctx, ports, inbox = _rig()
    st = ports["state"]
    st.check = lambda m: "utime off its clock" if m.header.utime > 10**9 else None
    inbox._trigger = command(1000, [3.0] * 10, seq=2)
    node.tick(ctx, inbox)
    inbox._trigger = None
    st._on_message("CASSIE_STATE", state(10**12, seq=9).encode())  # a corrupt utime
    node.tick(ctx, inbox)
    assert st.rejected == 1 and len(ctx.sent) == 1  # rejected at the edge: not answered
    st._on_message("CASSIE_STATE", state(1500, seq=3).encode())
    node.tick(ctx, inbox)
    assert len(ctx.sent) == 2 and ctx.sent[-1].ack == 3


def test_a_second_of_fills_keeps_the_edge_checks_clock_in_step():
    """A 1 kHz OSC's torques and the fills between them, with no state decoded on the way
    (a command carries its state's ack): the one state decoded in every 0.1 s keeps
    ``utime_step_s`` following the stream, so a state decoded after 1.5 s is admitted, not
    rejected as off its clock (measured live before: after a bridge's take-over it was, the
    bridge fell back to damping, and Cassie fell)."""
    from runtime.validate import InputCheck

    node, ctx, ports, inbox = _rig()
    st = ports["state"]
    st.check = InputCheck(robot_state_t, {"utime_step_s": [0.0, 1.0]})
    for k in range(2, 3002):  # 1.5 s of states at 2 kHz
        st._on_message("CASSIE_STATE", state(500 * k, seq=k & 0xFF).encode())
        inbox._trigger = command(500 * k, [3.0] * 10, seq=k & 0xFF) if k % 2 == 0 else None
        node.tick(ctx, inbox)
        st.fresh = False
    assert node.fills == 1500 and len(ctx.sent) == 3000 and st.rejected == 0
    st._on_message("CASSIE_STATE", state(500 * 3002, seq=3002 & 0xFF).encode())
    assert inbox.latest("state").header.utime == 500 * 3002  # admitted: in step
    assert st.rejected == 0
