"""The LCM bus as control loops want it: newest-message subscriptions, counted decode errors,
and one LCM domain per emulated host.

LCM queues the *oldest* messages when a subscriber falls behind; a control loop wants the
newest. A ``newest`` subscription keeps only the last raw message of its channel (counting the
ones it skipped) and decodes it on demand; an ``each`` subscription keeps every message in order
(for estimators and loggers). Bytes that are not the subscribed type are counted and dropped,
never raised into the loop.

Domains: on the robot, ttl-0 traffic never leaves the NUC, so the laptop never pays for the
NUC's 2 kHz channels and the NUC never hears the laptop's maps. Here all hosts are one machine,
so each host's local channels go to a multicast port of its own (``hw_config/hosts.yaml``), and
the channels that cross between hosts (``NETWORK_*``, and those declared ``scope: network``) to
the shared "network" port, with ttl 1. A process joins only the domains of the channels it
subscribes to (every datagram on a joined port reaches it, subscribed or not), and a process
that only publishes joins none.

Receiving reads the multicast sockets in the loop's own thread (``runtime.udpm``: LCM's wire
format, without LCM's receive thread and its ~30 us hand-off per message on this VM);
publishing goes through ``lcm.LCM``. Each domain gets up to two sockets, each asking the
kernel for its own channels only: one the loop waits on (its trigger), and one it reads when
it ticks (the other inputs), so a loop wakes for its trigger and nothing else, as dairlib's
LCM-driven loops do.
"""

from __future__ import annotations

import logging
import select
import time
from collections.abc import Callable, Collection, Mapping
from typing import Any
from urllib.parse import parse_qsl, urlencode, urlparse, urlunparse

import lcm

from runtime.errors import BusError, MulticastRouteError
from runtime.port_buffer import Policy, PortBuffer, worth_logging
from runtime.route import (
    DEFAULT_URL,
    FIX_HINT,
    check_multicast_route,
    has_multicast_route,
    multicast_group,
)
from runtime.udpm import UdpmReceiver

log = logging.getLogger(__name__)



#: the domain shared by every host: channels that cross between them
NETWORK = "network"


def with_query(url: str, **params: object) -> str:
    """``url`` with its query parameters updated (e.g. ttl, recv_buf_size)."""
    parsed = urlparse(url)
    query = dict(parse_qsl(parsed.query))
    query.update({k: str(v) for k, v in params.items() if v is not None})
    return urlunparse(parsed._replace(query=urlencode(query)))


def make_lcm(url: str) -> lcm.LCM:
    """Create an LCM instance, turning LCM's bare failure into an error that says how to fix it."""
    if url.startswith("udpm://"):
        check_multicast_route(url)
    try:
        return lcm.LCM(url)
    except RuntimeError as exc:
        if url.startswith("udpm://") and not has_multicast_route(multicast_group(url)[0]):
            raise MulticastRouteError(FIX_HINT) from exc
        raise BusError(
            f"could not create LCM on {url!r} ({exc}). Check the URL in hw_config/hosts.yaml "
            "(lcm.url), that multicast is enabled on the interface "
            "(`ip link show lo` should say MULTICAST), and that the port is free."
        ) from exc


class Subscription(PortBuffer):
    """One channel's inbox: the newest message (or every message, in order), decoded on demand."""

    def __init__(self, channel: str, msg_type: type | None, policy: Policy, capacity: int) -> None:
        super().__init__(policy, capacity)
        self.channel = self.name = channel
        self.msg_type = msg_type
        self._fingerprint: bytes | None = (
            msg_type._get_packed_fingerprint() if msg_type is not None else None  # type: ignore[attr-defined]
        )
        self.last_error: str = ""
        #: lcm-gen encodes a struct as its fingerprint, then its fields in order, nested
        #: structs without a fingerprint: a message whose first field is header_t carries
        #: header.utime as big-endian int64 at bytes 8..16
        self._header_first = msg_type is not None and next(
            iter(getattr(msg_type, "__slots__", ())), None) == "header"

    def newest_utime(self) -> int | None:
        """``header.utime`` of the newest undecoded payload, read without decoding it (None
        when there is none, or the type has no leading header)."""
        raw = self._raw
        if raw is None or not self._header_first or len(raw) < 16:
            return None
        return int.from_bytes(raw[8:16], "big", signed=True)

    def _on_message(self, _channel: str, data: bytes) -> None:
        self._stamp_arrival()
        if self._fingerprint is not None and data[:8] != self._fingerprint:
            self._count_error(f"{len(data)} bytes that are not {self.msg_type.__name__}")  # type: ignore[union-attr]
            return
        self.put(data)

    def _count_error(self, what: str) -> None:
        self.decode_errors += 1
        self.last_error = what
        if worth_logging(self.decode_errors):
            log.warning(
                "channel %s: dropped %s (%d so far)", self.channel, what, self.decode_errors
            )

    def _decode(self, data: bytes) -> Any | None:
        if self.msg_type is None:
            return data
        try:
            return self.msg_type.decode(data)  # type: ignore[attr-defined]
        except Exception as exc:
            self._count_error(f"a malformed {self.msg_type.__name__} ({exc})")
            return None


#: socket receive buffer of every bus (bytes): a loop busy in its tick must not lose the newest
#: message of a burst, nor fragments of a depth frame (~0.8 MB), to a full kernel buffer (the
#: Linux default is ~200 KB; the kernel caps the request at net.core.rmem_max)
DEFAULT_RECV_BUF = 2 << 20


class Bus:
    """LCM over one or more domains (one multicast port each), with per-channel ttl,
    newest-message subscriptions and header stamping.

    ``domains`` maps a domain name ("network", a host name) to its LCM URL and
    ``channel_domains`` a channel name to its domain (``Profile.domains`` and
    ``Profile.channel_domains``); a channel not listed there lives on the "network" domain,
    whose URL is ``url``. Without either, everything is on ``url``, as one shared bus.
    """

    def __init__(
        self,
        url: str = DEFAULT_URL,
        source: str = "",
        recv_buf_size: int | None = DEFAULT_RECV_BUF,
        domains: Mapping[str, str] | None = None,
        channel_domains: Mapping[str, str] | None = None,
    ) -> None:
        self.url = url
        self.source = source
        self.recv_buf_size = recv_buf_size
        self.domains: dict[str, str] = dict(domains or {})
        self.domains.setdefault(NETWORK, url)
        self.channel_domains: dict[str, str] = dict(channel_domains or {})
        if url.startswith("udpm://"):
            check_multicast_route(url)
        #: receiving sockets per (domain URL, wakes the loop), joined on first use
        self._rx: dict[tuple[str, bool], UdpmReceiver] = {}
        self._tx: dict[tuple[str, int], lcm.LCM] = {}  # publishing instance per (URL, ttl)
        self._subs: dict[str, Subscription] = {}
        self._seq: dict[str, int] = {}
        self._route: dict[str, tuple[str, int]] = {}  # channel -> (URL, ttl), memoised

    @classmethod
    def for_profile(cls, profile: Any, source: str = "", **kw: Any) -> Bus:
        """A bus over ``profile``'s domains (``runtime.config_types.Profile``)."""
        return cls(profile.lcm_url, source, domains=profile.domains,
                   channel_domains=profile.channel_domains, **kw)

    # -- routing ---------------------------------------------------------------------------
    def domain_of(self, channel: str) -> str:
        return self.channel_domains.get(channel, NETWORK)

    def route(self, channel: str) -> tuple[str, int]:
        """(LCM URL, ttl) of ``channel``: ttl 1 on the network domain for ``NETWORK_*`` and
        channels declared network-scoped, else 0."""
        r = self._route.get(channel)
        if r is None:
            domain = self.domain_of(channel)
            url = self.domains.get(domain, self.url)
            crosses = channel.startswith("NETWORK_") or self.channel_domains.get(channel) == NETWORK
            r = (url, 1 if crosses else 0)
            self._route[channel] = r
        return r

    def urls(self) -> list[str]:
        """Every distinct domain URL (for tools that listen to all of them)."""
        return list(dict.fromkeys(self.domains.values()))

    def _receiver(self, url: str, wake: bool = True) -> UdpmReceiver:
        rx = self._rx.get((url, wake))
        if rx is None:
            if url.startswith("udpm://"):
                check_multicast_route(url)
            try:
                rx = UdpmReceiver(url, self.recv_buf_size)
            except OSError as exc:
                raise BusError(
                    f"cannot listen to LCM on {url!r} ({exc.strerror}). Check the URL in "
                    "hw_config/hosts.yaml (lcm.url) and that multicast is enabled on the "
                    "interface (`ip link show lo` should say MULTICAST)."
                ) from exc
            self._rx[(url, wake)] = rx
        return rx

    def _sender(self, url: str, ttl: int) -> lcm.LCM:
        lc = self._tx.get((url, ttl))
        if lc is None:
            lc = make_lcm(with_query(url, ttl=ttl))
            self._tx[(url, ttl)] = lc
        return lc

    # -- receiving -------------------------------------------------------------------------
    def subscribe(
        self,
        channel: str,
        msg_type: type | None,
        policy: Policy = "newest",
        capacity: int = 4096,
        wake: bool = True,
        slot_us: int | None = None,
        second_half: bool = False,
    ) -> Subscription:
        """Subscribe to ``channel`` on its domain; ``msg_type`` None keeps raw bytes.
        ``wake`` False: its messages are read by ``handle_pending`` but never make
        ``filenos`` readable (a loop's non-trigger inputs). ``slot_us``: the kernel passes
        only the messages in the first half of each slot of sim time (``udpm``), or with
        ``second_half`` the others."""
        if channel in self._subs:
            return self._subs[channel]
        sub = Subscription(channel, msg_type, policy, capacity)
        if slot_us and not sub._header_first:
            slot_us = None
        self._receiver(self.route(channel)[0], wake).subscribe(channel, sub._on_message,
                                                               slot_us, second_half)
        self._subs[channel] = sub
        return sub

    def subscribe_raw(
        self,
        pattern: str,
        callback: Callable[[str, bytes], None],
        urls: list[str] | None = None,
    ) -> None:
        """Every message on channels matching ``pattern`` (a channel name, or a regex matched
        in full), raw, for loggers and dashboards: on the domain of the channel it names (the
        network domain for a regex), or on each of ``urls``."""
        plain = pattern.replace("\\", "").strip("^$")
        if urls is None:
            urls = [self.route(plain)[0]]
        exact = plain if plain.replace("_", "").isalnum() else pattern.strip("^$")
        for url in dict.fromkeys(urls):
            self._receiver(url).subscribe(exact, callback)

    def filenos(self) -> list[int]:
        """The file descriptors that become readable when a waking message arrives (one per
        joined domain; none for a bus that only publishes)."""
        return [rx.fileno() for (_, wake), rx in self._rx.items() if wake]

    def fileno(self) -> int:
        """The one descriptor of a single-domain bus (see ``filenos``)."""
        fds = self.filenos()
        if len(fds) != 1:
            raise BusError(f"this bus listens on {len(fds)} domains: use filenos()")
        return fds[0]

    def drain(self, timeout_s: float = 0.0) -> int:
        """Wait up to ``timeout_s`` for traffic, then handle everything pending; returns count."""
        fds = self.filenos()
        if not fds:
            if timeout_s > 0:
                time.sleep(timeout_s)
            return 0
        try:
            ready, _, _ = select.select(fds, [], [], max(0.0, timeout_s))
        except InterruptedError:
            return 0
        return self.handle_pending() if ready else 0

    def poll_every(self, period_s: float) -> int:
        """Sleep ``period_s``, then read everything that queued: for watchers (supervisor,
        logger, dashboard), which must never be woken per message. On this VM, waking a
        process on the other CPU costs its publisher ~30 us; a sleeping reader costs none."""
        time.sleep(period_s)
        return self.handle_pending()

    def handle_pending(self, ready_fds: Collection[int] = ()) -> int:
        """Handle every message already waiting, on every domain, without waiting.
        ``ready_fds``: descriptors a poll just found readable (saves a check each)."""
        n = 0
        for rx in self._rx.values():
            n += rx.drain(rx.fileno() in ready_fds)
        return n

    @property
    def decode_errors(self) -> int:
        return sum(s.decode_errors for s in self._subs.values())

    @property
    def subscriptions(self) -> dict[str, Subscription]:
        return self._subs

    # -- sending ---------------------------------------------------------------------------
    def stamp(self, channel: str, msg: Any) -> None:
        """Fill ``header.seq``, ``header.send_mono_ns`` and ``header.source`` of ``msg``."""
        header = getattr(msg, "header", None)
        if header is None:
            return
        seq = self._seq.get(channel, 0)
        self._seq[channel] = seq + 1
        header.seq = seq
        header.send_mono_ns = time.monotonic_ns()
        if not header.source:
            header.source = self.source

    def publish(self, channel: str, msg: Any) -> None:
        """Stamp and publish an lcm-gen message (or raw bytes) on ``channel``'s domain."""
        if isinstance(msg, (bytes, bytearray)):
            data = bytes(msg)
        else:
            self.stamp(channel, msg)
            data = msg.encode()
        self._sender(*self.route(channel)).publish(channel, data)

    def close(self) -> None:
        for rx in self._rx.values():
            rx.close()
        self._rx.clear()
        self._tx.clear()
