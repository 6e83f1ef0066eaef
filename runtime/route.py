"""Checks that this machine can route LCM's UDP multicast, and says how to fix it if not."""

from __future__ import annotations

import ipaddress
from urllib.parse import urlparse

#: the stack's LCM multicast group and network URL when hw_config names none (written once)
DEFAULT_GROUP = "239.255.76.67"
DEFAULT_URL = f"udpm://{DEFAULT_GROUP}:7667"

FIX_HINT = (
    "LCM needs a route for UDP multicast. This machine has none (no default route and no "
    "224.0.0.0/4 route). On a single machine, add one over loopback:\n"
    "    sudo ip route add 224.0.0.0/4 dev lo\n"
    "(and `sudo ip link set lo multicast on` if loopback has multicast off), or connect a "
    "network with a default route."
)


def multicast_group(url: str) -> tuple[str, int]:
    """The (group, port) of an ``udpm://GROUP:PORT?...`` LCM URL."""
    parsed = urlparse(url)
    if parsed.scheme != "udpm":
        raise ValueError(f"not an udpm:// LCM URL: {url!r}")
    host = parsed.hostname or DEFAULT_GROUP
    port = parsed.port or 7667
    return host, port


def _routes() -> list[tuple[int, int]]:
    """(destination, mask) of every IPv4 route in the kernel's table, as big-endian integers."""
    out: list[tuple[int, int]] = []
    try:
        with open("/proc/net/route", encoding="ascii") as f:
            lines = f.read().splitlines()[1:]
    except OSError:
        return out
    for line in lines:
        fields = line.split()
        if len(fields) < 8:
            continue
        # The kernel prints each address as the hex of a little-endian u32 of network-order bytes.
        dest = int.from_bytes(bytes.fromhex(fields[1])[::-1], "big")
        mask = int.from_bytes(bytes.fromhex(fields[7])[::-1], "big")
        out.append((dest, mask))
    return out


def has_multicast_route(group: str = DEFAULT_GROUP) -> bool:
    """True when some IPv4 route covers ``group`` (a default route counts)."""
    addr = int(ipaddress.IPv4Address(group))
    return any((addr & mask) == (dest & mask) for dest, mask in _routes())


def check_multicast_route(url: str) -> None:
    """Raise MulticastRouteError with the fix when the LCM URL's group has no route."""
    from runtime.errors import MulticastRouteError

    group, _ = multicast_group(url)
    if not has_multicast_route(group):
        raise MulticastRouteError(FIX_HINT)
