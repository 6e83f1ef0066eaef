"""Who belongs to a launch: the sim <-> bridge pairing token (which bridge the target PC takes
torques from) and the timing key (whose TIMING the supervisor takes).

The supervisor draws a token per launch and gives it to every process it starts in
``$CASSIE_LINK_TOKEN``; the torque bridge stamps it on each torque packet and the sim drops a
packet with another (``runtime.cassie_packets``, docs/udp_protocol.md). Light on purpose: the
supervisor imports it without numba or numpy.

The token travels in every torque packet, so anyone on the wire can read it; it keeps two
stacks apart, not an intruder out. The TIMING messages that tell the supervisor a process is
alive, well or faulty are signed instead: the supervisor draws a secret key per launch, hands
it to the processes it starts in ``$CASSIE_TIMING_KEY`` (never on the bus), and each TIMING
ends with an HMAC-SHA256 tag of the message before it (``loop_timing_t.auth``). A message that
names a real process and source but lacks the tag is refused and counted: before, one such
spoofed message could mark a process ready, healthy or faulty.
"""

from __future__ import annotations

import hashlib
import hmac
import os
from typing import Any

from runtime.errors import ConfigError

#: the environment variable holding the launch's pairing token (the supervisor draws one per
#: launch and gives it to every process it starts)
TOKEN_ENV = "CASSIE_LINK_TOKEN"
#: the token without a supervisor (a sim and a bridge started by hand, tests, the harness)
DEFAULT_TOKEN = 0x53534143  # b"CASS", little-endian


def link_token() -> int:
    """This launch's pairing token: ``$CASSIE_LINK_TOKEN``, else ``DEFAULT_TOKEN``."""
    raw = os.environ.get(TOKEN_ENV)
    if raw is None:
        return DEFAULT_TOKEN
    try:
        token = int(raw, 0)
    except ValueError:
        token = -1
    if not 0 < token < 1 << 32:
        raise ConfigError("the environment", TOKEN_ENV, f"{raw!r} is not a pairing token",
                          "an integer 1 .. 2**32 - 1, or unset (the supervisor sets one per "
                          "launch)")
    return token


def token_bytes(token: int) -> bytes:
    """The 4 bytes a torque packet carries at its token's offset."""
    return int(token).to_bytes(4, "little")


#: the environment variable holding the launch's timing key (hex; the supervisor's secret)
TIMING_KEY_ENV = "CASSIE_TIMING_KEY"
#: the tag's length: the last bytes of an encoded loop_timing_t (its ``auth`` field)
TAG_BYTES = 16


def timing_key() -> bytes | None:
    """This launch's timing key (``$CASSIE_TIMING_KEY``), None outside a supervised launch."""
    raw = os.environ.get(TIMING_KEY_ENV)
    if not raw:
        return None
    try:
        key = bytes.fromhex(raw)
    except ValueError:
        key = b""
    if len(key) < 16:
        raise ConfigError("the environment", TIMING_KEY_ENV, "is not a timing key",
                          "32 or more hex digits, or unset (the supervisor sets one per launch)")
    return key


def _tag(key: bytes, data: bytes | bytearray | memoryview) -> bytes:
    return hmac.digest(key, memoryview(data)[:-TAG_BYTES], hashlib.sha256)[:TAG_BYTES]


def sign_message(msg: Any, key: bytes) -> bytes:
    """A message whose last fields are ``int8_t auth_len; byte auth[auth_len]`` (TIMING, the
    deputies' orders and status) encoded with its ``auth``: the tag of ``key`` over the bytes
    before it (encoded with a zeroed tag of the right length, then the tag written in)."""
    msg.auth_len, msg.auth = TAG_BYTES, bytes(TAG_BYTES)
    data = bytearray(msg.encode())
    data[-TAG_BYTES:] = _tag(key, data)
    return bytes(data)


def message_signed(data: bytes, key: bytes) -> bool:
    """Whether an encoded message (see ``sign_message``) carries the tag of ``key``
    (constant-time compare)."""
    return len(data) > TAG_BYTES and hmac.compare_digest(_tag(key, data), data[-TAG_BYTES:])


def publish_timing(bus: Any, channel: str, msg: Any, key: bytes | None) -> None:
    """A TIMING message on ``bus`` (a ``runtime.bus.Bus``), signed with the launch's timing
    key when there is one: the supervisor takes no other."""
    if key is None:
        bus.publish(channel, msg)
        return
    bus.stamp(channel, msg)
    bus.publish(channel, sign_message(msg, key))
