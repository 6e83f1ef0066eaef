"""The packets' compiled decode (one numba call: size, version, kind, every float finite, copy)
accepts and rejects exactly what the numpy decode it replaced did, with the same messages,
and leaves the same bytes; the header and flag reads without numpy give the numpy values."""

from __future__ import annotations

import numpy as np
import pytest

from runtime.cassie_packets import (
    PROTOCOL_VERSION,
    InputPacket,
    OutputPacket,
    Packet,
    PacketError,
)


def numpy_decode(pkt: Packet, data: bytes | bytearray | memoryview) -> str | None:
    """The decode of runtime.cassie_packets before it was compiled (reference): None when
    ``data`` is accepted (and copied into ``pkt``), else the PacketError message."""
    layout = pkt.LAYOUT
    size = layout.itemsize
    if len(data) != size:
        return (f"{pkt.NAME} packet has {len(data)} bytes, expected exactly {size} "
                f"(protocol version {PROTOCOL_VERSION})")
    stage = bytearray(data)
    if stage[2] != PROTOCOL_VERSION:
        return (f"{pkt.NAME} packet has protocol version {stage[2]}, this end speaks "
                f"{PROTOCOL_VERSION}: rebuild both ends from the same runtime.cassie_packets")
    if stage[3] != pkt.KIND:
        return (f"{pkt.NAME} packet has kind byte {stage[3]:#04x}, expected {pkt.KIND:#04x} "
                f"({chr(pkt.KIND)!r}): is the peer sending to the wrong port?")
    rec = np.frombuffer(bytes(stage), dtype=layout)
    for name in layout.names:
        if layout[name].base.kind == "f" and not np.isfinite(rec[name]).all():
            return f"{pkt.NAME} packet field {name!r} holds NaN or inf"
    pkt.buffer[:] = stage
    return None


SPECIAL = np.array([0.0, -0.0, 5e-324, -5e-324, 2.2250738585072014e-308, 1.7976931348623157e308,
                    -1.7976931348623157e308, 1.0, -2.5])
NON_FINITE = np.array([np.inf, -np.inf, np.nan, -np.nan,
                       np.frombuffer(b"\x01\x00\x00\x00\x00\x00\xf8\x7f", "<f8")[0],  # NaN payload
                       np.frombuffer(b"\xff\xff\xff\xff\xff\xff\xff\xff", "<f8")[0]])


def _datagrams(cls: type[Packet], rng: np.random.Generator) -> list[bytes]:
    """Valid packets with ordinary and extreme floats, and every way of being invalid: a NaN
    or inf in each float, every size from empty to one too long, wrong version and kind."""
    pkt = cls()
    floats = pkt.floats
    out: list[bytes] = []
    for _ in range(40):
        floats[:] = rng.choice(SPECIAL, floats.size) * rng.choice([1.0, -0.5, 0.75], floats.size)
        pkt.bytes_array[:2] = rng.integers(0, 256, 2)
        good = bytes(pkt.buffer)
        out.append(good)
        bad = cls()
        for j in range(floats.size):  # each float in turn, with each kind of NaN and inf
            bad.buffer[:] = good
            bad.floats[j] = NON_FINITE[(j + len(out)) % NON_FINITE.size]
            out.append(bytes(bad.buffer))
    good = out[0]
    out += [good[:n] for n in range(0, len(good), 7)] + [good + b"\0"]
    for k, v in ((2, PROTOCOL_VERSION + 1), (2, 0), (3, ord("S") + ord("T") - good[3]), (3, 0)):
        b = bytearray(good)
        b[k] = v
        out.append(bytes(b))
    return out


@pytest.mark.parametrize("cls", [InputPacket, OutputPacket])
@pytest.mark.parametrize("kind", [bytes, bytearray, memoryview])
def test_compiled_decode_accepts_rejects_and_copies_as_numpy_did(cls: type[Packet],
                                                                 kind: type) -> None:
    rng = np.random.default_rng(7)
    data = _datagrams(cls, rng)
    got, want = cls(), cls()
    rejected = 0
    for raw in data:
        before = bytes(got.buffer)
        msg = numpy_decode(want, kind(raw))
        if msg is None:
            got.decode(kind(raw))
        else:
            rejected += 1
            with pytest.raises(PacketError) as err:
                got.decode(kind(raw))
            assert str(err.value) == msg
            assert bytes(got.buffer) == before  # the last good packet survives
        assert bytes(got.buffer) == bytes(want.buffer)
        assert got.seq == int(want._record["seq"][0]) and got.ack == int(want._record["ack"][0])
    assert 0 < rejected < len(data)


def test_header_and_flags_read_and_write_the_bytes_numpy_did() -> None:
    pkt = InputPacket()
    for seq, ack, flags in ((0, 0, 0), (255, 1, 1), (300, -1, 0xDEADBEEF), (7, 256, 1 << 31)):
        pkt._flags[0] = flags
        raw = pkt.encode(seq, ack)
        rec = np.frombuffer(raw, dtype=pkt.LAYOUT)
        assert (rec["seq"][0], rec["ack"][0]) == (seq & 0xFF, ack & 0xFF)
        assert (pkt.seq, pkt.ack) == (seq & 0xFF, ack & 0xFF)
        assert pkt.flags == int(rec["flags"][0]) == flags
