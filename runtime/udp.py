"""Plain UDP ports for the target PC <-> NUC link (binary packets, as on the robot)."""

from __future__ import annotations

import errno
import math
import os
import select
import socket

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
    ) -> None:
        """``drop_ratio``: the kernel drops this share of the datagrams at random before this
        socket sees them (a lossy link, for fault tests: ``LOSS_ENV``)."""
        super().__init__(policy, capacity)
        self.address = address
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, recv_buf_size)
        try:
            self.sock.bind(address)
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
