"""The LCM bus as control loops want it: newest-message subscriptions, counted decode errors.

LCM queues the *oldest* messages when a subscriber falls behind; a control loop wants the
newest. A ``newest`` subscription keeps only the last raw message of its channel (counting the
ones it skipped) and decodes it on demand; an ``each`` subscription keeps every message in order
(for estimators and loggers). Bytes that are not the subscribed type are counted and dropped,
never raised into the loop. Channels named ``NETWORK_*`` are published with ttl 1 (they cross
from the NUC to the laptop), the rest with ttl 0, as on the robot.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from typing import Any
from urllib.parse import parse_qsl, urlencode, urlparse, urlunparse

import lcm

from runtime.errors import BusError, MulticastRouteError
from runtime.port_buffer import Policy, PortBuffer
from runtime.route import FIX_HINT, check_multicast_route, has_multicast_route, multicast_group

log = logging.getLogger(__name__)


DEFAULT_URL = "udpm://239.255.76.67:7667"


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
        self.channel = channel
        self.msg_type = msg_type
        self._fingerprint: bytes | None = (
            msg_type._get_packed_fingerprint() if msg_type is not None else None  # type: ignore[attr-defined]
        )
        self.last_error: str = ""

    def _on_message(self, _channel: str, data: bytes) -> None:
        self._stamp_arrival()
        if self._fingerprint is not None and data[:8] != self._fingerprint:
            self._count_error(f"{len(data)} bytes that are not {self.msg_type.__name__}")  # type: ignore[union-attr]
            return
        self.put(data)

    def _count_error(self, what: str) -> None:
        self.decode_errors += 1
        self.last_error = what
        if self.decode_errors in (1, 10, 100, 1000) or self.decode_errors % 10000 == 0:
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
    """LCM with per-channel ttl, newest-message subscriptions and header stamping."""

    def __init__(
        self,
        url: str = DEFAULT_URL,
        source: str = "",
        recv_buf_size: int | None = DEFAULT_RECV_BUF,
    ) -> None:
        self.url = url
        self.source = source
        self._lc = make_lcm(with_query(url, ttl=0, recv_buf_size=recv_buf_size))
        self._lc_network: lcm.LCM | None = None  # ttl=1 publisher, made on first use
        self._subs: dict[str, Subscription] = {}
        self._raw_subs: list[Any] = []
        self._seq: dict[str, int] = {}

    # -- receiving -------------------------------------------------------------------------
    def subscribe(
        self,
        channel: str,
        msg_type: type | None,
        policy: Policy = "newest",
        capacity: int = 4096,
        lcm_queue: int = 1000,
    ) -> Subscription:
        """Subscribe to ``channel``; ``msg_type`` None keeps raw bytes."""
        if channel in self._subs:
            return self._subs[channel]
        sub = Subscription(channel, msg_type, policy, capacity)
        handle = self._lc.subscribe(_exact(channel), sub._on_message)
        handle.set_queue_capacity(lcm_queue)
        self._subs[channel] = sub
        return sub

    def subscribe_raw(
        self, pattern: str, callback: Callable[[str, bytes], None], lcm_queue: int = 100000
    ) -> None:
        """Every message on channels matching the regex ``pattern``, raw, for loggers/dashboards."""
        handle = self._lc.subscribe(pattern, callback)
        handle.set_queue_capacity(lcm_queue)
        self._raw_subs.append(handle)

    def fileno(self) -> int:
        return self._lc.fileno()

    def drain(self, timeout_s: float = 0.0) -> int:
        """Wait up to ``timeout_s`` for traffic, then handle everything pending; returns count."""
        n = 0
        if self._handle(max(0, int(timeout_s * 1000))):
            n = 1
            while self._handle(0):
                n += 1
        return n

    def handle_pending(self) -> int:
        """Handle every message already queued without waiting."""
        n = 0
        while self._handle(0):
            n += 1
        return n

    def _handle(self, timeout_ms: int) -> bool:
        try:
            return self._lc.handle_timeout(timeout_ms) > 0
        except OSError:
            # LCM's select was interrupted by a signal (SIGINT on shutdown): nothing handled.
            return False

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
        """Stamp and publish an lcm-gen message (or raw bytes) on ``channel``."""
        if isinstance(msg, (bytes, bytearray)):
            data = bytes(msg)
        else:
            self.stamp(channel, msg)
            data = msg.encode()
        self._lcm_for(channel).publish(channel, data)

    def _lcm_for(self, channel: str) -> lcm.LCM:
        if not channel.startswith("NETWORK_"):
            return self._lc
        if self._lc_network is None:
            self._lc_network = make_lcm(with_query(self.url, ttl=1))
        return self._lc_network

    def close(self) -> None:
        for sub in list(self._raw_subs):
            try:
                self._lc.unsubscribe(sub)
            except Exception:
                pass
        self._raw_subs.clear()
        self._lc = None  # type: ignore[assignment]
        self._lc_network = None


def _exact(channel: str) -> str:
    """LCM subscribes by regex: escape a literal channel name so ``A.B`` does not match ``AxB``."""
    import re

    return re.escape(channel)
