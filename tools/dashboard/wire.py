"""Cheap reads of raw LCM bytes: the header and a message's leading fixed-size fields.

Full lcm-gen decoding costs about 10 us per robot state; the dashboard sees about 6000 messages
a second on the 2 kHz channels and needs only their headers (for hop latencies) and a few
scalars. Every lcm-gen message starts with an 8-byte type fingerprint followed by
``header_t`` (utime, seq, send_mono_ns as big-endian int64, then a length-prefixed string),
so those can be read with ``struct`` at a fraction of the cost. The fingerprint check ensures a
changed message definition is rejected (and counted) instead of misread.
"""

from __future__ import annotations

import struct
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

_HEADER = struct.Struct(">qqqI")  # utime, seq, send_mono_ns, len(source) + 1
_HEADER_END = 8 + _HEADER.size


def fingerprint(msg_type: type) -> bytes:
    """The 8-byte packed fingerprint that starts every encoded message of ``msg_type``."""
    return msg_type._get_packed_fingerprint()  # type: ignore[attr-defined]


@dataclass
class Headers:
    """Columns of the headers (and optional leading fields) of a run of same-type messages.

    ``index`` maps each row back to the position of its message in the input list, since
    messages that fail the fingerprint check are skipped.
    """

    utime: np.ndarray  # int64, microseconds of sim time
    seq: np.ndarray  # int64
    mono_ns: np.ndarray  # int64, CLOCK_MONOTONIC at publish
    index: np.ndarray  # int64, position in the input list
    fields: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))  # float64 (n, k)
    rejected: int = 0

    def __len__(self) -> int:
        return len(self.utime)


def read_headers(
    msgs: Sequence[bytes], fp: bytes, lead: struct.Struct | None = None
) -> Headers:
    """Headers of ``msgs`` whose fingerprint is ``fp``; with ``lead``, also the fields after it.

    ``lead`` is a big-endian ``struct`` format for the fixed-size fields that directly follow
    the header (e.g. ``>dd`` for two doubles); they are returned as float64 columns.
    """
    n = len(msgs)
    utime = np.empty(n, np.int64)
    seq = np.empty(n, np.int64)
    mono = np.empty(n, np.int64)
    index = np.empty(n, np.int64)
    k = len(lead.unpack(bytes(lead.size))) if lead is not None else 0
    fields = np.empty((n, k), np.float64)
    m = 0
    rejected = 0
    for i, data in enumerate(msgs):
        if data[:8] != fp or len(data) < _HEADER_END:
            rejected += 1
            continue
        try:
            u, s, t, slen = _HEADER.unpack_from(data, 8)
            if lead is not None:
                fields[m] = lead.unpack_from(data, _HEADER_END + slen)
        except struct.error:
            rejected += 1
            continue
        utime[m], seq[m], mono[m], index[m] = u, s, t, i
        m += 1
    return Headers(utime[:m], seq[:m], mono[:m], index[:m], fields[:m], rejected)
