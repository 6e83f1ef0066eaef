"""`cassie log PROFILE FILE`: record every LCM message of a profile's domains into one LCM log.

The stock ``lcm-logger`` wakes on every message (its receive thread), and every wake of a
process on the other CPU costs the publisher ~30 us on this VM: logging the NUC's 2 kHz
traffic that way costs the control loops. This logger sleeps instead, and every ``--period-ms``
reads what queued in its sockets (one per domain: each host's bus and the network), with
the kernel's arrival time of each datagram (SO_TIMESTAMPNS), so the log says when each
message arrived although it is read in batches; it writes a standard LCM log (lcm.EventLog,
readable by lcm-logplayer, lcm-spy, `cassie report`) in arrival order, and counts datagrams
the kernel dropped on a full socket buffer (SO_RXQ_OVFL), which it reports at the end.
"""

from __future__ import annotations

import argparse
import signal
import sys
import threading
import time
from collections import Counter
from pathlib import Path

import lcm

from runtime.udpm import UdpmReceiver

#: enough socket buffer for a whole period of the busiest domain (depth frames: 0.8 MB each)
RECV_BUF = 16 << 20


class BatchLogger:
    """Reads each domain every ``period_s`` and appends the messages, in arrival order."""

    def __init__(self, urls: list[str], out: Path, period_s: float = 0.02) -> None:
        self.period_s = period_s
        self.out = out
        out.parent.mkdir(parents=True, exist_ok=True)
        self.log = lcm.EventLog(str(out), "w", overwrite=True)
        self.rxs = [UdpmReceiver(u, RECV_BUF, filtered=False, timestamps=True)
                    for u in dict.fromkeys(urls)]
        self._batch: list[tuple[int, str, bytes]] = []
        for rx in self.rxs:
            rx.subscribe(".*", self._on(rx))
        self.counts: Counter[str] = Counter()
        self.stop = threading.Event()

    def _on(self, rx: UdpmReceiver):  # type: ignore[no-untyped-def]
        def file(channel: str, data: bytes) -> None:
            self._batch.append((rx.last_recv_utime, channel, data))
        return file

    def flush(self) -> int:
        """Read every socket now and write what was there, oldest first."""
        for rx in self.rxs:
            rx.drain()
        batch = self._batch
        if not batch:
            return 0
        batch.sort(key=lambda e: e[0])
        write = self.log.write_event
        for utime, channel, data in batch:
            if channel != "LCM_SELF_TEST":
                write(utime, channel, data)
                self.counts[channel] += 1
        n = len(batch)
        self._batch = []
        return n

    def run(self, duration_s: float | None = None) -> None:
        end = None if duration_s is None else time.monotonic() + duration_s
        while not self.stop.is_set() and (end is None or time.monotonic() < end):
            self.stop.wait(self.period_s)
            self.flush()
        self.flush()
        self.log.close()

    @property
    def dropped(self) -> int:
        return sum(rx.kernel_dropped for rx in self.rxs)

    @property
    def malformed(self) -> int:
        return sum(rx.bad + rx.fragments_dropped for rx in self.rxs)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="cassie log", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("profile", help="launch profile: its LCM domains are recorded")
    ap.add_argument("file", type=Path, help="the LCM log to write (overwritten)")
    ap.add_argument("--period-ms", type=float, default=20.0,
                    help="how often the sockets are read (default 20)")
    ap.add_argument("--duration", type=float, default=None, help="stop after S seconds")
    args = ap.parse_args(argv)
    from runtime.config import load_profile

    profile = load_profile(args.profile)
    urls = list(profile.domains.values()) or [profile.lcm_url]
    logger = BatchLogger(urls, args.file, args.period_ms / 1000.0)
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: logger.stop.set())
    print(f"logging {len(logger.rxs)} LCM domains into {args.file} every "
          f"{args.period_ms:g} ms", flush=True)
    logger.run(args.duration)
    total = sum(logger.counts.values())
    print(f"{total} messages on {len(logger.counts)} channels; {logger.dropped} datagrams "
          f"dropped by the kernel (full socket buffer); {logger.malformed} malformed",
          flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
