"""The inbox of one input port: the newest payload, or every payload in order, with counters.

Shared by LCM subscriptions (``runtime.bus.Subscription``) and UDP ports
(``runtime.udp.UdpReceiver``); subclasses decode raw bytes on demand (``_decode``), so a loop
that only wants the newest message never pays for decoding the ones it skips.
"""

from __future__ import annotations

import logging
import threading
import time
from collections import deque
from collections.abc import Callable, Mapping
from typing import Any, Literal

Policy = Literal["newest", "each"]
log = logging.getLogger(__name__)


def worth_logging(count: int, every: int = 10000) -> bool:
    """Whether the ``count``-th bad message is logged: the 1st, 10th, 100th and 1000th, then
    every ``every``-th (a flood must not flood the log)."""
    return count in (1, 10, 100, 1000) or count % every == 0


class PortBuffer:
    """Newest-slot (``newest``) or bounded FIFO (``each``) of raw payloads.

    Filing (``put``) and taking (``latest``, ``pop``, ``trim``) may run on different threads
    (a loop with a receive thread): both touch the slot under one short lock, and decoding
    happens outside it, so a slow decode never holds up the receiver.
    """

    def __init__(self, policy: Policy, capacity: int) -> None:
        self.policy = policy
        self._raw: bytes | None = None
        self._decoded: Any | None = None
        self._queue: deque[bytes] = deque(maxlen=capacity)
        self.fresh = False
        self.received = 0
        self.stale_skipped = 0
        self.decode_errors = 0
        self.overflowed = 0
        self.last_receive_ns = 0
        #: the edge check (``runtime.validate.InputCheck``): a decoded message it rejects is
        #: dropped and counted, and the previous good one stays the newest
        self.check: Callable[[Any], str | None] | None = None
        self.rejected = 0
        self.last_rejected = ""
        self.name = ""  # for the log (a channel name)
        self._lock = threading.Lock()

    def put(self, data: bytes) -> None:
        """File one arrived payload (the receive path: no decoding here)."""
        with self._lock:
            if self.policy == "each":
                if len(self._queue) == self._queue.maxlen:
                    self.overflowed += 1
                self._queue.append(data)
            else:
                if self.fresh:
                    self.stale_skipped += 1
                self._raw = data
            self.fresh = True

    def _decode(self, data: bytes) -> Any | None:
        """Payload -> message, or None when it is malformed (subclasses count why)."""
        return data

    def _admit(self, data: bytes) -> Any | None:
        """Decode, then the edge check: the message, or None (malformed or rejected)."""
        msg = self._decode(data)
        if msg is None or self.check is None:
            return msg
        why = self.check(msg)
        if why is None:
            return msg
        self.rejected += 1
        self.last_rejected = why
        if worth_logging(self.rejected):
            log.warning("input %s: rejected a message at the edge: %s (%d so far)",
                        self.name or "?", why, self.rejected)
        return None

    def latest(self) -> Any | None:
        """The newest message, decoded and marked consumed (the previous good one if corrupt)."""
        self.take()
        return self._decoded

    def take(self) -> Any | None:
        """The newest message if it is good (decoded, admitted), marked consumed; None when
        nothing new came or what came was malformed or rejected. A trigger is taken, never
        ``latest``: a bad message must not re-run the loop on the previous good one."""
        with self._lock:
            if self.policy == "each":
                raws = list(self._queue)
                self._queue.clear()
            else:
                raws = [] if self._raw is None else [self._raw]
                self._raw = None
            self.fresh = False
        good = None
        for raw in raws:
            msg = self._admit(raw)
            if msg is not None:
                self._decoded = good = msg
        return good

    def pop(self) -> Any | None:
        """Next message in arrival order (``each`` policy); None when the queue is empty."""
        while True:
            with self._lock:
                if not self._queue:
                    self.fresh = False
                    return None
                raw = self._queue.popleft()
                self.fresh = bool(self._queue)
            msg = self._admit(raw)
            if msg is not None:
                self._decoded = msg
                return msg

    def discard(self) -> None:
        """Drop the newest payload unread (``newest`` policy): a trigger a rate limit skips."""
        with self._lock:
            self._raw = None
            self.fresh = False

    def pending(self) -> int:
        return len(self._queue) if self.policy == "each" else int(self._raw is not None)

    def trim(self, keep: int) -> int:
        """Drop all but the newest ``keep`` queued payloads (counted as stale); returns how many."""
        with self._lock:
            drop = max(len(self._queue) - keep, 0)
            for _ in range(drop):
                self._queue.popleft()
            self.stale_skipped += drop
        return drop

    def peek(self) -> Any | None:
        """The last decoded message, without consuming anything."""
        return self._decoded

    def raw(self) -> bytes | None:
        """The newest payload not decoded yet (``newest`` policy), or None; unchecked."""
        return self._raw

    def _stamp_arrival(self) -> None:
        self.received += 1
        self.last_receive_ns = time.monotonic_ns()


class PortInbox:
    """``runtime.node.Inbox`` over a node's port buffers, live and in the harness alike."""

    def __init__(self, ports: Mapping[str, PortBuffer]) -> None:
        self._ports = ports
        self._trigger: Any | None = None

    def latest(self, role: str) -> Any | None:
        port = self._ports[role]
        # (a payload a loop read undecoded, ``newest_raw``, is still the newest: decode it)
        return port.latest() if port.fresh or port.raw() is not None else port.peek()

    def is_fresh(self, role: str) -> bool:
        return self._ports[role].fresh

    def trigger(self) -> Any | None:
        return self._trigger

    def set_trigger(self, msg: Any | None) -> None:
        """The runner's part: the message this tick is on (None: a tick without one)."""
        self._trigger = msg

    def pop(self, role: str) -> Any | None:
        return self._ports[role].pop()

    def newest_raw(self, role: str) -> bytes | None:
        return self._ports[role].raw()
