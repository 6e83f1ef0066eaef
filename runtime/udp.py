"""Plain UDP ports for the target PC <-> NUC link (binary packets, as on the robot)."""

from __future__ import annotations

import errno
import math
import os
import select
import socket
import time

from runtime.errors import BusError
from runtime.port_buffer import Policy, PortBuffer
from runtime.udpm import attach_filter, random_drop_filter

#: environment: the share of datagrams every UDP receiver of a process drops (fault tests:
#: loss on the target PC <-> NUC link, both ways, where netfilter and netem are missing)
LOSS_ENV = "CASSIE_UDP_LOSS"


def loss_from_env() -> float:
    """``$CASSIE_UDP_LOSS`` as a share in [0, 1) (0 when unset); a clear error otherwise."""
    raw = os.environ.get(LOSS_ENV, "").strip()
    if not raw:
        return 0.0
    try:
        ratio = float(raw)
    except ValueError:
        ratio = math.nan
    if not 0.0 <= ratio < 1.0:
        raise BusError(f"{LOSS_ENV}={raw!r}: a share of datagrams to drop, in [0, 1) "
                       "(e.g. 0.05); unset it for no loss")
    return ratio


class UdpReceiver(PortBuffer):
    """A bound, non-blocking UDP socket that keeps the newest datagram (or every one, in order)."""

    def __init__(
        self,
        address: tuple[str, int],
        policy: Policy = "newest",
        capacity: int = 4096,
        recv_buf_size: int = 1 << 20,
        drop_ratio: float = 0.0,
        bind_wait_s: float = 0.0,
    ) -> None:
        """``drop_ratio``: the kernel drops this share of the datagrams at random before this
        socket sees them (a lossy link, for fault tests: ``LOSS_ENV``). ``bind_wait_s``: while
        the port is taken, try again for this long (a successor that starts as its crashed
        predecessor is still being torn down: the kernel closes a killed process's sockets
        only after it has unmapped its memory, ~10-30 ms)."""
        super().__init__(policy, capacity)
        self.address = address
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, recv_buf_size)
        try:
            _bind(self.sock, address, bind_wait_s)
        except OSError as exc:
            self.sock.close()
            hint = (
                " (another process already holds it: is a previous run still alive?)"
                if exc.errno == errno.EADDRINUSE
                else ""
            )
            raise BusError(
                f"cannot bind UDP {address[0]}:{address[1]}: {exc.strerror}{hint}"
            ) from exc
        self.sock.setblocking(False)
        self._loss_prog = (attach_filter(self.sock, random_drop_filter(drop_ratio))
                           if drop_ratio > 0.0 else None)
        self._buf = bytearray(65536)
        self._ready = select.poll()  # a waiting datagram, without a failed (raising) read
        self._ready.register(self.sock.fileno(), select.POLLIN)

    def fileno(self) -> int:
        return self.sock.fileno()

    def drain(self, known_ready: bool = False) -> int:
        """Read every datagram waiting in the socket; returns how many. ``known_ready``: the
        caller's poll just said a datagram is there (one "is there more?" check saved)."""
        n = 0
        ready, recv = self._ready.poll, self.sock.recv
        while known_ready or ready(0):
            known_ready = False
            try:
                data = recv(65536)  # one copy, into a bytes object of the datagram's size
            except OSError:
                break
            self._stamp_arrival()
            self.put(data)
            n += 1
        return n

    def close(self) -> None:
        self.sock.close()


def _bind(sock: socket.socket, address: tuple[str, int], wait_s: float) -> None:
    """``sock.bind(address)``, retried every 0.5 ms for ``wait_s`` while the port is taken."""
    end = time.monotonic() + wait_s
    while True:
        try:
            sock.bind(address)
            return
        except OSError as exc:
            if exc.errno != errno.EADDRINUSE or time.monotonic() >= end:
                raise
        time.sleep(0.0005)


class UdpSender:
    """An unbound UDP socket that sends datagrams to one peer address."""

    def __init__(self, address: tuple[str, int]) -> None:
        self.address = address
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sent = 0
        self.send_errors = 0

    def send(self, data: bytes) -> None:
        try:
            self.sock.sendto(data, self.address)
            self.sent += 1
        except OSError:
            # The peer is not up yet (ECONNREFUSED from a previous ICMP) or the buffer is full:
            # UDP is lossy by design here, and both ends count what goes missing.
            self.send_errors += 1

    def close(self) -> None:
        self.sock.close()


#: datagrams answered only after a resend, in a row, before the timeout backs off for good
RESENT_IN_ROW_BACKOFF = 3


class ResendTimer:
    """How long a lockstep sender waits for the answer to a datagram before it sends it again:
    TCP's retransmission timer (RFC 6298) on the measured round trips.

    ``timeout_s = srtt + 4 * rttvar`` (the smoothed round trip and its mean deviation, gains
    1/8 and 1/4), kept within ``[min_s, max_s]``; each expiry doubles it (up to ``max_s``)
    until an answer comes, and a datagram that was sent again gives no sample, since its
    answer may be to either copy (Karn's rule). Unlike TCP, a new datagram starts again from
    the measured figure, not the backed-off one: on this link a loss is a dropped datagram,
    not a congested peer (with the doubled wait kept, 20 % loss each way ran at half the
    speed). A fixed 10 ms timeout made each lost datagram cost ten ~1 ms cycles: at 20 % loss
    each way the lockstep stack crawled (1.3 s of sim time in 40 s). Times are the caller's,
    in seconds, so a test can drive it."""

    def __init__(self, min_s: float, max_s: float) -> None:
        if not 0.0 < min_s <= max_s:
            raise ValueError(f"resend timeout bounds {min_s} .. {max_s} s: need 0 < min <= max")
        self.min_s, self.max_s = min_s, max_s
        self.timeout_s = max_s  # nothing measured yet (RFC 6298 starts high, too)
        self.measured_s = max_s  # srtt + 4 rttvar, bounded: where each new datagram starts
        self.srtt = math.nan
        self.rttvar = 0.0
        self.samples = 0
        self._sent_at = math.nan  # first send of the datagram awaiting its answer; nan: resent
        self._resent_in_row = 0  # answered datagrams in a row that had to be sent again

    def sent(self, now: float) -> None:
        """A new datagram went out (not a resend)."""
        self._sent_at = now
        self.timeout_s = self.measured_s

    def answered(self, now: float) -> None:
        """Its answer came: one round-trip sample, unless it had been resent."""
        sent, self._sent_at = self._sent_at, math.nan
        if math.isnan(sent):
            # no sample (Karn). Should the round trip have grown past the timeout for good,
            # every datagram would now expire once and never give a sample: after
            # RESENT_IN_ROW_BACKOFF such datagrams in a row the starting figure doubles (at
            # random loss, 20 % each way, that happens to ~5 % of runs of three and is undone
            # by the next clean samples)
            self._resent_in_row += 1
            if self._resent_in_row >= RESENT_IN_ROW_BACKOFF:
                self._resent_in_row = 0
                self.measured_s = min(2.0 * self.measured_s, self.max_s)
            return
        self._resent_in_row = 0
        r = now - sent
        if self.samples == 0:
            self.srtt, self.rttvar = r, r / 2
        else:
            self.rttvar += 0.25 * (abs(self.srtt - r) - self.rttvar)
            self.srtt += 0.125 * (r - self.srtt)
        self.samples += 1
        self.timeout_s = self.measured_s = min(max(self.srtt + 4.0 * self.rttvar, self.min_s),
                                               self.max_s)

    def expired(self) -> None:
        """No answer within ``timeout_s``: the datagram is sent again; wait twice as long."""
        self._sent_at = math.nan
        self.timeout_s = min(2.0 * self.timeout_s, self.max_s)
