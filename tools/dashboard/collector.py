"""The LCM side of the dashboard: a thread that only files raw messages into bounded buffers.

The collector never decodes anything: its callback appends the bytes to the channel's
buffer and returns, so the dashboard keeps up with the bus whatever Rerun is doing. Each
channel's buffer holds at most ``capacity`` messages; when it is full the oldest message is
dropped and counted, so a slow or stalled batcher costs a bounded amount of memory and never
pushes back on the publishers. It listens on the LCM domain of each channel it shows (a host's
bus or the network: ``Profile.channel_domains``), and only on those.
"""

from __future__ import annotations

import logging
import threading
from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass

from runtime.bus import Bus

log = logging.getLogger(__name__)

DEFAULT_RECV_BUF = 8 * 1024 * 1024


@dataclass
class ChannelStats:
    """Counts for one channel since the collector started."""

    received: int = 0
    dropped: int = 0  # evicted from the full buffer before the batcher took them


class Collector:
    """Subscribes to ``capacities`` (channel name -> buffer size) and buffers raw messages."""

    def __init__(
        self,
        url: str,
        capacities: dict[str, int],
        recv_buf_size: int | None = DEFAULT_RECV_BUF,
        keep_bytes: dict[str, int] | None = None,
        domains: Mapping[str, str] | None = None,
        channel_domains: Mapping[str, str] | None = None,
    ) -> None:
        """``keep_bytes`` (channel -> n) keeps only the first n bytes of that channel's
        messages: enough for the header when the rest (a depth image) is never used."""
        if any(c < 1 for c in capacities.values()):
            raise ValueError(f"every buffer capacity must be >= 1, got {capacities}")
        self.url = url
        self.capacities = dict(capacities)
        self.keep_bytes = dict(keep_bytes or {})
        self._lock = threading.Lock()
        self._buffers: dict[str, deque[bytes]] = {
            ch: deque(maxlen=cap) for ch, cap in self.capacities.items()
        }
        self.stats: dict[str, ChannelStats] = {ch: ChannelStats() for ch in self.capacities}
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._bus = Bus(url, source="dashboard", recv_buf_size=recv_buf_size, domains=domains,
                        channel_domains=channel_domains)
        for ch in self.capacities:
            self._bus.subscribe_raw(ch, self._on_message)

    def _on_message(self, channel: str, data: bytes) -> None:
        """LCM callback: file the bytes, evicting (and counting) the oldest when full."""
        with self._lock:
            buf = self._buffers.get(channel)
            if buf is None:
                return
            st = self.stats[channel]
            st.received += 1
            if len(buf) == buf.maxlen:
                st.dropped += 1
            keep = self.keep_bytes.get(channel)
            buf.append(data if keep is None else data[:keep])

    def take(self) -> dict[str, list[bytes]]:
        """Everything buffered since the last call, per channel, oldest first."""
        out: dict[str, list[bytes]] = {}
        with self._lock:
            for ch, buf in self._buffers.items():
                if buf:
                    out[ch] = list(buf)
                    buf.clear()
        return out

    def pending(self) -> dict[str, int]:
        """Messages waiting in each buffer."""
        with self._lock:
            return {ch: len(buf) for ch, buf in self._buffers.items()}

    def totals(self) -> tuple[int, int]:
        """(received, dropped) over all channels."""
        with self._lock:
            return (
                sum(s.received for s in self.stats.values()),
                sum(s.dropped for s in self.stats.values()),
            )

    # -- thread ------------------------------------------------------------------------------
    def start(self) -> None:
        """Start the receiving thread (a daemon: it never keeps the process alive)."""
        if self._thread is not None:
            return
        self._thread = threading.Thread(target=self._run, name="dashboard-lcm", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                self._bus.poll_every(0.02)  # batched: the stack is never woken for it
            except Exception:  # never let one bad message end the collection
                log.exception("LCM receive failed")

    def stop(self, timeout_s: float = 1.0) -> None:
        """Stop the thread (waiting up to ``timeout_s``) and close the bus."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout_s)
            if self._thread.is_alive():
                log.warning("LCM thread did not stop within %.1f s; leaving it", timeout_s)
                return
        self._bus.close()
