"""Short, long, wrong-version, wrong-kind and non-finite datagrams are rejected with a
PacketError, counted, and never crash the target PC or change the torque it applies; a
well-formed torque packet with another launch's pairing token is dropped and counted as
foreign."""

from __future__ import annotations

import struct

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from runtime.cassie_packets import (
    INPUT_SIZE,
    OUTPUT_SIZE,
    PROTOCOL_VERSION,
    TOKEN_AT,
    InputPacket,
    OutputPacket,
    PacketError,
    encode_input,
)
from runtime.pairing import DEFAULT_TOKEN, token_bytes
from sim.target_pc import TargetPC, make_core
from sim.terrain import flat

GOOD = encode_input(1, 0, np.full(10, 2.0))


@pytest.fixture(scope="module")
def tpc() -> TargetPC:
    return TargetPC(make_core(flat()), "realtime")


def _valid_input(data: bytes) -> bool:
    if len(data) != INPUT_SIZE or data[2] != PROTOCOL_VERSION or data[3] != ord("T"):
        return False
    if data[TOKEN_AT:TOKEN_AT + 4] != token_bytes(DEFAULT_TOKEN):
        return False
    return bool(np.isfinite(np.frombuffer(data, "<f8", 10, 8)).all())


@settings(max_examples=300, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.one_of(
    st.binary(max_size=600),
    st.binary(min_size=INPUT_SIZE, max_size=INPUT_SIZE),
    st.builds(lambda b, i, v: b[:i] + bytes([v]) + b[i + 1:], st.just(GOOD),
              st.integers(0, INPUT_SIZE - 1), st.integers(0, 255)),
))
def test_fuzzed_datagrams_are_counted_never_raised(tpc: TargetPC, data: bytes) -> None:
    tpc.receive(GOOD)
    tpc.core.command(tpc.inp.torque)
    before_bad = tpc.link.malformed + tpc.link.foreign
    ok = tpc.receive(data)  # must not raise
    assert ok == _valid_input(data)
    assert tpc.link.malformed + tpc.link.foreign == before_bad + (0 if ok else 1)
    if not ok:  # the last good packet survives a rejected one
        np.testing.assert_array_equal(tpc.inp.torque, np.full(10, 2.0))
    out = tpc.realtime_cycle(data)  # the whole cycle survives it too
    assert len(out) == OUTPUT_SIZE


@pytest.mark.parametrize("data, reason", [
    (GOOD[:-1], "91 bytes"),
    (GOOD + b"\0", "93 bytes"),
    (b"", "0 bytes"),
    (GOOD[:2] + bytes([PROTOCOL_VERSION + 1]) + GOOD[3:], "protocol version 3"),
    (GOOD[:3] + b"S" + GOOD[4:], "kind byte"),
    (GOOD[:8] + struct.pack("<d", float("nan")) + GOOD[16:], "NaN or inf"),
    (GOOD[:16] + struct.pack("<d", float("inf")) + GOOD[24:], "NaN or inf"),
])
def test_each_kind_of_malformed_packet_says_why(data: bytes, reason: str) -> None:
    with pytest.raises(PacketError, match=reason):
        InputPacket().decode(data)


@settings(max_examples=200, deadline=None)
@given(st.one_of(st.binary(max_size=600), st.binary(min_size=OUTPUT_SIZE, max_size=OUTPUT_SIZE)))
def test_the_nuc_side_rejects_fuzzed_state_packets_with_packet_error_only(data: bytes) -> None:
    pkt = OutputPacket()
    try:
        pkt.decode(data)
    except PacketError:
        assert bytes(pkt.buffer[4:]) == bytes(OUTPUT_SIZE - 4)  # left untouched
    else:
        assert len(data) == OUTPUT_SIZE and data[3] == ord("S")


def test_state_packet_rejects_a_torque_packet() -> None:
    with pytest.raises(PacketError, match="476"):
        OutputPacket().decode(GOOD)


def test_node_counts_garbage_and_keeps_stepping(driver_factory) -> None:
    drv = driver_factory("realtime", {"terrain": "flat", "camera_render": "inline"})
    node = drv.node
    for k in range(20):
        drv.tick(command=b"\x00garbage" * k)
    assert node.tpc.link.malformed == 20
    assert node.core.steps == 20
    assert len(drv.sent["robot_output"]) == 21
    assert "bad 20" in node.status()


def test_a_torque_packet_of_another_launch_is_dropped_and_counted_as_foreign() -> None:
    """Issue 14, fault 11: the sim applied any well-formed torque packet; now only its
    bridge's (the launch's pairing token), in real time and in lockstep."""
    rt = TargetPC(make_core(flat()), "realtime", token=0x1234)
    assert rt.take(encode_input(1, 0, np.full(10, 3.0), token=0x1234))
    assert not rt.take(encode_input(2, 0, np.full(10, 50.0)))  # the default token: not ours
    assert rt.link.foreign == 1 and rt.link.malformed == 0
    assert "pairing token 0x53534143, not this launch's 0x00001234" in rt.last_error
    np.testing.assert_array_equal(rt.inp.torque, np.full(10, 3.0))
    lock = TargetPC(make_core(flat()), "lockstep", token=0x1234)
    seq = lock.encode_state()[0]  # the state a command must answer
    t0 = lock.core.time
    assert lock.lockstep_cycle(encode_input(1, seq, np.zeros(10), token=0x4321)) is None
    assert lock.core.time == t0 and lock.link.foreign == 1  # no step on a foreign answer
    assert lock.lockstep_cycle(encode_input(1, seq, np.zeros(10), token=0x1234)) is not None
    assert lock.core.time > t0
