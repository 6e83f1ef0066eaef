"""`cassie bench bridge`: the torque bridge under the live runner, fed at 2 kHz over LCM.

The bridge is the one of ``hw_config/sim.yaml`` (``processes.torque_bridge.process.make_node``,
its gains, ``answer_on: command`` in real time, its ``applied_input`` at 200 Hz), run by
``runtime.loops.LiveRunner`` in a process of its own pinned to the NUC's CPU at SCHED_FIFO
(``runtime.scheduling``, as ``cassie run`` does). A feeder process on the same CPU stands in
for the state estimator and the OSC: at 2 kHz of wall clock it publishes a ``robot_state_t``
on the state channel, then a ``torque_command_t`` computed "from" it on the torque channel
(``runtime.bus.Bus``, lcm-gen messages of the real sizes), at the OSC's priority; a UDP sink
process on the target PC's CPU reads the torque packets every 0.5 ms, as the sim does (so a
packet wakes nobody there). LCM and UDP use ports of the benchmark's own. ``--contend MB``
(default 8) adds a nice-19 process on the bridge's CPU that sweeps memory, as the estimator
and the OSC leave the caches in the stack.

Figures come from the bridge's own ``TIMING`` samples after a warm-up: CPU share of a core,
thread CPU per tick (the node's tick: the state decode, watchdog, clamps, packet, and the
200 Hz ``applied_input``) beside its wall time, response time from the command's send to
the packet sent, deadline misses. ``--baseline REV`` times the bridge of git revision REV
(its ``processes/``, ``runtime/``, ``lcmtypes/``, ``hw_config/``) in runs interleaved with
this tree's. Nothing is asserted.
"""

from __future__ import annotations

import argparse
import json
import socket
import time
from pathlib import Path
from typing import Any

import numpy as np

from tools.benchmarks.common import REPO, extract_tree, free_udp_port, until_sigterm
from tools.benchmarks.sim import (
    LOOP_ROWS,
    add_live_options,
    bench_lcm_url,
    child_env,
    collect_timing,
    contend,
    pin,
    report_interleaved,
    run_figures,
    run_interleaved,
    run_live,
    start_child,
    start_contender,
    stop_child,
)

PERIOD_S = 0.0005
BRIDGE_TREE = ("processes", "runtime", "lcmtypes", "hw_config")
MODULE = "tools.benchmarks.bridge"


def _feeder(seconds: float, cpus: list[int], fifo: int) -> int:
    """The estimator and OSC stand-in: a state every 0.5 ms, then its torque command at the
    OSC's rate (sim.yaml's ``max_rate_hz``: the first state of each slot; the bridge answers
    the others itself, ``params.fill_hz``)."""
    from lcmtypes import robot_state_t, torque_command_t
    from runtime.bus import Bus
    from runtime.config import load_profile

    notes = pin(cpus, fifo)
    profile = load_profile(REPO / "hw_config" / "sim.yaml")
    bridge = profile.processes["torque_bridge"]
    state_ch, torque_ch = bridge.inputs["state"].name, bridge.inputs["torque"].name
    bus = Bus.for_profile(profile, source="feeder")
    osc_hz = profile.processes["osc"].max_rate_hz
    slot_us = round(1e6 / osc_hz) if osc_hz else 0
    rng = np.random.default_rng(0)
    s = robot_state_t()
    s.num_positions, s.num_velocities, s.num_motors = 35, 32, 10
    s.q = rng.normal(0, 0.3, 35).tolist()
    s.motor_torque = [0.0] * 10
    c = torque_command_t()
    c.num_motors = 10
    c.status = "walking"
    limit = np.array([112.5, 112.5, 195.2, 195.2, 45.0] * 2)
    # a walk's worth of torques: within the limits, a few over them (the bridge clamps)
    torques = (rng.normal(0.0, 0.35, (997, 10)) * limit).tolist()
    vels = rng.normal(0.0, 2.0, (991, 32)).tolist()
    stop = until_sigterm()
    period_ns = int(PERIOD_S * 1e9)
    t0 = time.monotonic_ns()
    end = t0 + int(seconds * 1e9)
    k = 0
    while not stop.is_set():
        target = t0 + k * period_ns
        now = time.monotonic_ns()
        if now < target:
            time.sleep((target - now) / 1e9)
        utime = k * 500
        s.header.utime = utime
        s.v = vels[k % 991]
        s.packet_seq = k & 0xFF
        bus.publish(state_ch, s)
        if not slot_us or utime % slot_us < slot_us // 2:
            c.header.utime = utime
            c.state_packet_seq = s.packet_seq
            c.torque = torques[k % 997]
            bus.publish(torque_ch, c)
        k += 1
        if time.monotonic_ns() >= end:
            break
    print(json.dumps({"published": k, "notes": notes}), flush=True)
    return 0


def _sink(port: int, cpus: list[int]) -> int:
    """The target PC stand-in: every 0.5 ms, read (and count) the torque packets that came,
    as the sim's periodic loop does; like it, it never waits on the socket, so a packet sent
    to it wakes nobody."""
    pin(cpus, None)
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", port))
    sock.setblocking(False)
    buf = bytearray(2048)
    n = 0
    stop = until_sigterm()
    period_ns = int(PERIOD_S * 1e9)
    t0 = time.monotonic_ns()
    k = 0
    while not stop.is_set():
        k += 1
        wait = t0 + k * period_ns - time.monotonic_ns()
        if wait > 0:
            time.sleep(wait / 1e9)
        while True:
            try:
                sock.recv_into(buf)
            except (BlockingIOError, InterruptedError):
                break
            n += 1
    print(json.dumps({"received": n}), flush=True)
    return 0


def _bridge(tree: str | None, sink_port: int, seconds: float) -> int:
    """The bridge of ``tree``'s ``hw_config/sim.yaml`` under the live runner, its UDP link
    moved to the sink's port."""
    return run_live(tree, "torque_bridge", seconds, {"robot_input": sink_port})


def _run_once(tree: Path | None, args: argparse.Namespace, nuc_cpus: list[int],
              target_cpus: list[int], feeder_fifo: int) -> dict[str, Any]:
    """One live run of the bridge of ``tree`` (None: this one) with a fresh feeder and sink."""
    url = bench_lcm_url()
    env = child_env(url)
    port = free_udp_port()
    sink = start_child(["--role", "sink", "--port", str(port), "--cpus",
                        ",".join(map(str, target_cpus))], env, MODULE)
    assert sink.stdout is not None
    sink.stdout.readline()
    cmd = ["--role", "bridge", "--port", str(port), "--seconds",
           str(args.seconds + args.warmup + 3.0)]  # it starts before the feeder
    if tree is not None:
        cmd += ["--tree", str(tree)]
    hog = start_contender(args.contend, nuc_cpus, MODULE)
    bridge = start_child(cmd, env, MODULE)
    feeder = None
    try:
        # the bridge's first TIMING says it is set up: start feeding then
        msgs = collect_timing(bridge, url, "torque_bridge", 60.0, until_first=True)
        if not msgs:
            raise SystemExit(f"the bridge did not start:\n{stop_child(bridge)[1][-3000:]}")
        feeder = start_child(["--role", "feeder", "--seconds", str(args.seconds + args.warmup),
                              "--cpus", ",".join(map(str, nuc_cpus)), "--fifo",
                              str(feeder_fifo)], env, MODULE)
        msgs += collect_timing(bridge, url, "torque_bridge", args.seconds + args.warmup + 60.0)
        bridge.wait(timeout=30.0)
    finally:
        _, bridge_err = stop_child(bridge)
        feed_out = stop_child(feeder)[0] if feeder is not None else ""
        sink_out, _ = stop_child(sink)
        if hog is not None:
            stop_child(hog)
    fig, delta = run_figures("bridge", bridge, bridge_err, msgs, args.warmup)
    for name in ("packets_sent", "watchdog_trips", "clamps", "nan_rejects"):
        fig[name] = int(delta(name))
    try:
        fig["feeder_published"] = json.loads(feed_out.strip().splitlines()[-1])["published"]
        fig["sink_received"] = json.loads(sink_out.strip().splitlines()[-1])["received"]
    except (ValueError, IndexError, KeyError):
        pass
    return fig


ROWS = (
    *LOOP_ROWS,
    ("response (command sent -> packet sent) median (ms)", "input_age_median_ms"),
    ("response p99 (ms)", "input_age_p99_ms"),
    ("deadline miss ratio", "deadline_miss_ratio"),
    ("ticks per second", "rate_hz"),
    ("stale commands skipped", "stale_skipped"),
    ("clamped torques", "clamps"),
    ("ticks", "ticks"),
)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="cassie bench bridge", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    add_live_options(ap, "bridge", "the estimator and OSC",
                     ("feeder", "sink", "bridge", "contend"))
    ap.add_argument("--port", type=int, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    cpus = [int(c) for c in args.cpus.split(",") if c]
    if args.role == "feeder":
        return _feeder(args.seconds, cpus, args.fifo)
    if args.role == "sink":
        return _sink(args.port, cpus)
    if args.role == "bridge":
        return _bridge(args.tree, args.port, args.seconds)
    if args.role == "contend":
        return contend(args.mb, cpus)

    from runtime.config import load_profile

    profile = load_profile(REPO / "hw_config" / "sim.yaml")
    bridge = profile.processes["torque_bridge"]
    nuc_cpus = list(bridge.cpu_affinity or ())
    target_cpus = list(profile.processes["sim"].cpu_affinity or ())
    feeder_fifo = profile.processes["osc"].rt_priority or 0
    pin(target_cpus, None)  # this process reads TIMING on the target PC's CPU
    base_tree = extract_tree(args.baseline, BRIDGE_TREE) if args.baseline else None
    merged, load0, load1 = run_interleaved(
        base_tree, args.repeats,
        lambda tree: _run_once(tree, args, nuc_cpus, target_cpus, feeder_fifo),
        lambda fig: f"{fig['rate_hz']:.0f} ticks/s")
    figures: dict[str, Any] = {
        "description": f"torque bridge of hw_config/sim.yaml under LiveRunner (CPU {nuc_cpus}, "
                       f"SCHED_FIFO {bridge.rt_priority}), fed a state every 0.5 ms and a torque "
                       f"command at the OSC's rate over LCM from CPU {nuc_cpus}, UDP sink on CPU "
                       f"{target_cpus}; contender sweeping {args.contend:g} MB on the "
                       f"bridge's CPU; {args.repeats} x {args.seconds:g} s",
        "contend_mb": args.contend,
    }
    this = merged["this"]
    return report_interleaved(
        "bridge", "torque bridge at 2 kHz under LiveRunner (this tree)", args, figures, merged,
        (load0, load1), ROWS,
        [("states published / packets received by the sink",
          f"{this.get('feeder_published')} / {this.get('sink_received')}")])


if __name__ == "__main__":
    raise SystemExit(main())
