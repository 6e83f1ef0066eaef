"""`cassie bench lcm`: Python-to-Python LCM hop latency against a raw UDP baseline.

Two real processes on this machine. This one sends pings at a fixed rate on absolute deadlines;
a peer process answers each ping. The peer measures the one-way hop (its receive time minus the
ping's monotonic send time: one clock for every process on a host) and returns it in the pong,
so both the one-way hop and the round trip are measured; a ping without a pong counts as lost.
The same is done over a plain UDP socket pair in the same run, as the floor that LCM's own
overhead (multicast, marshalling, the Python binding) adds to.
"""

from __future__ import annotations

import argparse
import os
import random
import select
import signal
import socket
import struct
import subprocess
import sys
import time

import numpy as np

from tools.benchmarks.common import print_table, progress, summarize, write_json

_UDP = struct.Struct("<qqd")  # seq, send_mono_ns, one-way hop measured by the peer (us)


def _lcm_peer(url: str) -> int:
    """Answer PING with PONG; vx carries the one-way hop in microseconds."""
    from lcmtypes import command_t
    from runtime.bus import Bus

    bus = Bus(url, source="bench_peer")
    stop = False

    def on_sig(*_: object) -> None:
        nonlocal stop
        stop = True

    signal.signal(signal.SIGTERM, on_sig)
    signal.signal(signal.SIGINT, on_sig)

    def on_ping(_channel: str, data: bytes) -> None:
        now = time.monotonic_ns()
        ping = command_t.decode(data)
        pong = command_t()
        pong.header.utime = ping.header.seq
        pong.vx = (now - ping.header.send_mono_ns) / 1e3
        bus.publish("BENCH_PONG", pong)

    bus.subscribe_raw("BENCH_PING", on_ping)
    print("ready", flush=True)
    while not stop:
        bus.drain(0.1)
    return 0


def _udp_peer(port_in: int, port_out: int) -> int:
    rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    rx.bind(("127.0.0.1", port_in))
    tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(0))
    print("ready", flush=True)
    while True:
        data = rx.recv(64)
        now = time.monotonic_ns()
        seq, sent, _ = _UDP.unpack(data)
        tx.sendto(_UDP.pack(seq, sent, (now - sent) / 1e3), ("127.0.0.1", port_out))


def _spawn_peer(args: list[str]) -> subprocess.Popen[str]:
    env = dict(os.environ)
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    env["PYTHONPATH"] = os.pathsep.join([root, env.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    p = subprocess.Popen(
        [sys.executable, "-m", "tools.benchmarks.lcm", "--peer", *args],
        stdout=subprocess.PIPE,
        text=True,
        env=env,
    )
    line = p.stdout.readline() if p.stdout else ""
    if line.strip() != "ready":
        p.kill()
        raise RuntimeError(f"benchmark peer did not start: {line!r}")
    return p


def _pace(rate_hz: float, seconds: float, send, poll,  # type: ignore[no-untyped-def]
          desc: str = "pings") -> int:
    """Call send(seq) on absolute deadlines at rate_hz for seconds, polling in between
    (``desc`` names the progress bar)."""
    period = int(1e9 / rate_hz)
    n = int(seconds * rate_hz)
    bar = progress(n, desc, unit="ping")
    t0 = time.monotonic_ns() + 10_000_000
    for k in range(n):
        slot = t0 + k * period
        while True:
            wait = slot - time.monotonic_ns()
            if wait <= 150_000:
                break
            poll((wait - 150_000) / 1e9)
        # between the polls and the spin before the send: the last pong is in by now (a hop
        # is ~0.1 ms of the period's 0.5-1 ms), and a redraw (at most twice a second) only
        # eats into the spin; the send's own time stamp is taken in send()
        bar.update(1)
        while time.monotonic_ns() < slot:
            pass
        send(k)
    bar.close()
    end = time.monotonic_ns() + 200_000_000
    while time.monotonic_ns() < end:
        poll(0.01)
    return n


def measure_lcm(url: str, rate_hz: float, seconds: float) -> tuple[np.ndarray, np.ndarray, int]:
    """(one-way hop us, round trip us, pings sent) for LCM between two processes."""
    from lcmtypes import command_t
    from runtime.bus import Bus

    peer = _spawn_peer(["lcm", url])
    try:
        bus = Bus(url, source="bench")
        sent_at: dict[int, int] = {}
        hop: list[float] = []
        rtt: list[float] = []

        def on_pong(_c: str, data: bytes) -> None:
            now = time.monotonic_ns()
            m = command_t.decode(data)
            t = sent_at.pop(int(m.header.utime), None)
            if t is not None:
                hop.append(m.vx)
                rtt.append((now - t) / 1e3)

        bus.subscribe_raw("BENCH_PONG", on_pong)
        ping = command_t()

        def send(k: int) -> None:
            sent_at[k] = time.monotonic_ns()
            bus.publish("BENCH_PING", ping)  # header.seq counts from 0 with k

        time.sleep(0.3)
        n = _pace(rate_hz, seconds, send, lambda t: bus.drain(t), f"LCM {rate_hz:g} Hz")
        return np.array(hop), np.array(rtt), n
    finally:
        peer.terminate()
        peer.wait(5)


def measure_udp(rate_hz: float, seconds: float) -> tuple[np.ndarray, np.ndarray, int]:
    """The same exchange over a plain loopback UDP socket pair: the baseline."""
    port_in, port_out = random.randint(30000, 40000), random.randint(40001, 50000)
    rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    rx.bind(("127.0.0.1", port_out))
    rx.setblocking(False)
    tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    peer = _spawn_peer(["udp", str(port_in), str(port_out)])
    try:
        sent_at: dict[int, int] = {}
        hop: list[float] = []
        rtt: list[float] = []

        def poll(timeout: float) -> None:
            r, _, _ = select.select([rx], [], [], timeout)
            while r:
                try:
                    data = rx.recv(64)
                except BlockingIOError:
                    break
                now = time.monotonic_ns()
                seq, _sent, one_way = _UDP.unpack(data)
                t = sent_at.pop(seq, None)
                if t is not None:
                    hop.append(one_way)
                    rtt.append((now - t) / 1e3)

        def send(k: int) -> None:
            now = time.monotonic_ns()
            sent_at[k] = now
            tx.sendto(_UDP.pack(k, now, 0.0), ("127.0.0.1", port_in))

        n = _pace(rate_hz, seconds, send, poll, f"UDP {rate_hz:g} Hz")
        return np.array(hop), np.array(rtt), n
    finally:
        peer.terminate()
        peer.wait(5)


def run(rates: list[float], seconds: float, url: str) -> dict[str, float]:
    figures: dict[str, float] = {}
    for rate in rates:
        tag = f"{int(rate)}hz"
        for name, fn in (
            ("lcm", lambda r=rate: measure_lcm(url, r, seconds)),
            ("udp", lambda r=rate: measure_udp(r, seconds)),
        ):
            hop, rtt, n = fn()
            figures.update(_percentiles(hop / 1e3, f"{name}_{tag}_hop"))
            figures.update(_percentiles(rtt / 1e3, f"{name}_{tag}_rtt"))
            figures[f"{name}_{tag}_sent"] = n
            figures[f"{name}_{tag}_loss_ratio"] = 1.0 - hop.size / n if n else 0.0
        for stat in ("median", "p99"):
            udp = figures[f"udp_{tag}_hop_{stat}_ms"]
            figures[f"lcm_over_udp_{tag}_hop_{stat}_ratio"] = (
                figures[f"lcm_{tag}_hop_{stat}_ms"] / udp if udp > 0 else float("nan")
            )
    return figures


def _percentiles(a: np.ndarray, prefix: str) -> dict[str, float]:
    s = summarize(a, prefix)
    s.pop(f"{prefix}_count", None)
    s.pop(f"{prefix}_mean_ms", None)
    return s


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="cassie bench lcm",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    ap.add_argument("--json", default=None, help="write the figures to this JSON file")
    ap.add_argument("--seconds", type=float, default=10.0, help="per rate and transport")
    ap.add_argument("--rates", default="1000,2000", help="comma-separated ping rates in Hz")
    ap.add_argument("--peer", nargs="+", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.peer:
        if args.peer[0] == "lcm":
            return _lcm_peer(args.peer[1])
        return _udp_peer(int(args.peer[1]), int(args.peer[2]))
    url = os.environ.get("CASSIE_LCM_URL") or f"udpm://239.255.76.67:{random.randint(20000, 60000)}"
    rates = [float(r) for r in args.rates.split(",")]
    figures = run(rates, args.seconds, url)
    for rate in rates:
        tag = f"{int(rate)}hz"
        rows: list[tuple[str, ...]] = []
        for stat in ("median", "p99", "p999", "max"):
            lcm_v = figures[f"lcm_{tag}_hop_{stat}_ms"]
            udp_v = figures[f"udp_{tag}_hop_{stat}_ms"]
            rows.append((f"one-way hop {stat} (ms)", f"{lcm_v:.3f}", f"{udp_v:.3f}",
                         f"{lcm_v / udp_v:.2f}"))
        for stat in ("median", "p99"):
            rows.append((f"round trip {stat} (ms)", f"{figures[f'lcm_{tag}_rtt_{stat}_ms']:.3f}",
                         f"{figures[f'udp_{tag}_rtt_{stat}_ms']:.3f}", ""))
        rows.append((f"loss (of {figures[f'lcm_{tag}_sent']} pings)",
                     f"{figures[f'lcm_{tag}_loss_ratio']:.4%}",
                     f"{figures[f'udp_{tag}_loss_ratio']:.4%}", ""))
        print_table(f"LCM vs UDP, Python to Python, {int(rate)} Hz, {args.seconds:.0f} s", rows,
                    columns=["", "LCM", "UDP", "LCM / UDP"], justify="lrrr")
    write_json(
        args.json,
        "lcm",
        {"description": "LCM hop vs raw UDP between two Python processes on one host", **figures},
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
