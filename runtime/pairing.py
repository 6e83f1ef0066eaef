"""The sim <-> bridge pairing token: which bridge the target PC takes torques from.

The supervisor draws a token per launch and gives it to every process it starts in
``$CASSIE_LINK_TOKEN``; the torque bridge stamps it on each torque packet and the sim drops a
packet with another (``runtime.cassie_packets``, docs/udp_protocol.md). Light on purpose: the
supervisor imports it without numba or numpy.
"""

from __future__ import annotations

import os

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
