"""Plain UDP ports for the target PC <-> NUC link (binary packets, as on the robot)."""

from __future__ import annotations

import errno
import socket
import time
from collections import deque

from runtime.errors import BusError


class UdpReceiver:
    """A bound, non-blocking UDP socket that keeps the newest datagram (or every one, in order)."""

    def __init__(
        self,
        address: tuple[str, int],
        policy: str = "newest",
        capacity: int = 4096,
        recv_buf_size: int = 1 << 20,
    ) -> None:
        self.address = address
        self.policy = policy
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, recv_buf_size)
        try:
            self.sock.bind(address)
        except OSError as exc:
            self.sock.close()
            hint = (
                " (another process already holds it: is a previous run still alive?)"
                if (exc.errno == errno.EADDRINUSE)
                else ""
            )
            raise BusError(
                f"cannot bind UDP {address[0]}:{address[1]}: {exc.strerror}{hint}"
            ) from exc
        self.sock.setblocking(False)
        self._buf = bytearray(65536)
        self._queue: deque[tuple[bytes, int]] = deque(maxlen=capacity)
        self._newest: bytes | None = None
        self._decoded_last: bytes | None = None
        self.fresh = False
        self.received = 0
        self.stale_skipped = 0
        self.decode_errors = 0
        self.last_receive_ns = 0

    def fileno(self) -> int:
        return self.sock.fileno()

    def drain(self) -> int:
        """Read every datagram waiting in the socket; returns how many."""
        n = 0
        while True:
            try:
                size = self.sock.recv_into(self._buf)
            except (BlockingIOError, InterruptedError):
                break
            data = bytes(self._buf[:size])
            now = time.monotonic_ns()
            self.received += 1
            self.last_receive_ns = now
            n += 1
            if self.policy == "each":
                self._queue.append((data, now))
            else:
                if self.fresh:
                    self.stale_skipped += 1
                self._newest = data
            self.fresh = True
        return n

    def latest(self) -> bytes | None:
        if self.policy == "each":
            while self._queue:
                self._decoded_last = self._queue.popleft()[0]
        elif self._newest is not None:
            self._decoded_last, self._newest = self._newest, None
        self.fresh = False
        return self._decoded_last

    def pop(self) -> bytes | None:
        if self._queue:
            self._decoded_last = self._queue.popleft()[0]
            self.fresh = bool(self._queue)
            return self._decoded_last
        self.fresh = False
        return None

    def pending(self) -> int:
        return len(self._queue) if self.policy == "each" else int(self._newest is not None)

    def trim(self, keep: int) -> int:
        """Drop all but the newest ``keep`` queued datagrams (counted as stale)."""
        drop = max(len(self._queue) - keep, 0)
        for _ in range(drop):
            self._queue.popleft()
        self.stale_skipped += drop
        return drop

    def peek(self) -> bytes | None:
        return self._decoded_last

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
