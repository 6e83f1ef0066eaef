"""`cassie bench sim`: the real sim process at 2 kHz under the live runner, with a UDP peer.

The sim is the one of ``hw_config/sim.yaml`` (``sim.process.make_node``, the profile's gains
and output rates, no depth camera as in that profile unless ``--camera``), run by
``runtime.loops.LiveRunner`` in a process of its own pinned to the target PC's CPU, at
SCHED_FIFO once set up (``runtime.scheduling``, as ``cassie run`` does). A peer *process* on the
NUC's CPU (SCHED_FIFO, the state estimator's priority) stands in for the NUC: it decodes every
state packet and answers it at once with a torque packet (zero torques, so the start-up
holder keeps the robot standing). Both links are real UDP sockets on 127.0.0.1, on ports of
the benchmark's own, and LCM runs on a multicast port of its own, so a stack running on the
machine is neither heard nor disturbed.

Figures come from the sim's own ``TIMING`` messages (the raw per-tick samples the runner
publishes), after a warm-up: the process's CPU share of a core (all its threads, per window),
the loop thread's CPU time per tick (``thread_time`` around the runner's input poll and the
node's tick: the work, which preemption does not inflate) beside its wall time, the
real-time factor (sim time over wall time), slots skipped (overruns) and deadline misses.

``--baseline REV``: the sim of git revision REV (its ``sim/``, ``runtime/``, ``lcmtypes/`` and
``hw_config/``, extracted with ``git archive``) is timed in the same run, in runs interleaved
with this tree's (baseline, this, baseline, this, ...), so both see the same machine load; the
table puts them side by side with their ratio. Nothing is asserted: the machine is shared.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import random
import signal
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from tools.benchmarks.common import (
    REPO,
    extract_tree,
    free_udp_port,
    machine_load,
    print_table,
    say,
    until_sigterm,
    write_json,
)
from tools.benchmarks.common import progress as progress_bar

PERIOD_MS = 0.5
#: what a baseline revision's sim needs from its tree
SIM_TREE = ("sim", "runtime", "lcmtypes", "hw_config")


# -- shared by the live benchmarks (this one and tools.benchmarks.bridge) -------------------


def bench_lcm_url() -> str:
    """A multicast port of this benchmark's own (its host domains are the next few ports)."""
    return f"udpm://239.255.76.67:{random.randrange(20000, 60000, 10)}"


def use_tree(tree: str | None) -> Path:
    """Import ``runtime``, ``sim``, ... from ``tree`` (a baseline) rather than this one; call
    before importing any of them. Returns the tree's root."""
    if not tree:
        return REPO
    root = Path(tree).resolve()
    sys.path.insert(0, str(root))
    return root


def pin(cpus: Sequence[int] | None, fifo: int | None) -> list[str]:
    """Pin this process to ``cpus`` and ask for SCHED_FIFO priority ``fifo`` (best effort:
    what could not be applied is said, never raised)."""
    notes = []
    if cpus:
        try:
            os.sched_setaffinity(0, list(cpus))
        except OSError as exc:
            notes.append(f"affinity {list(cpus)} failed: {exc.strerror}")
    if fifo:
        try:
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(int(fifo)))
        except OSError as exc:
            notes.append(f"SCHED_FIFO {fifo} failed: {exc.strerror}")
    return notes


def collect_timing(child: subprocess.Popen[str], url: str, process: str,
                   timeout_s: float, until_first: bool = False) -> list[Any]:
    """Every ``loop_timing_t`` of ``process`` on ``url``'s TIMING until ``child`` exits (or
    ``timeout_s``; with ``until_first``, until the first one: the loop is set up). Polls
    every 50 ms, so this process never wakes per message."""
    from lcmtypes import loop_timing_t
    from runtime.bus import Bus

    bus = Bus(url, source="bench")
    sub = bus.subscribe("TIMING", loop_timing_t, "each", capacity=100_000)
    msgs: list[Any] = []
    end = time.monotonic() + timeout_s
    try:
        while time.monotonic() < end:
            done = child.poll() is not None
            bus.poll_every(0.05)
            while (m := sub.pop()) is not None:
                if m.process == process:
                    msgs.append(m)
            if done or (until_first and msgs):
                break
    finally:
        bus.close()
    return msgs


def loop_figures(msgs: list[Any], warmup_s: float) -> dict[str, Any]:
    """Figures of one loop from its TIMING windows, dropping the first ``warmup_s``: the raw
    per-tick samples (CPU and wall ms), the process's CPU share, rates and counters."""
    windows = [m for m in msgs if m.ticks > 0]
    t, keep = 0.0, []
    for m in windows:
        t += m.window_s
        if t > warmup_s:
            keep.append(m)
    if keep:  # a window the input stopped in (a message-driven loop's feeder) is left out
        rate = float(np.median([m.rate_hz for m in keep]))
        keep = [m for m in keep if m.rate_hz >= 0.8 * rate]
    if len(keep) < 2:
        return {"windows": len(keep)}
    wall = sum(m.window_s for m in keep[1:])
    cpu = np.concatenate([np.asarray(m.cpu_ms, dtype=float) for m in keep])
    exe = np.concatenate([np.asarray(m.exec_ms, dtype=float) for m in keep])
    late = np.concatenate([np.asarray(m.lateness_ms, dtype=float) for m in keep])
    age = np.concatenate([np.asarray(m.input_age_ms, dtype=float) for m in keep])
    age = age[age >= 0]  # -1: the tick had no timestamped input
    ticks = sum(m.ticks for m in keep)
    first, last = keep[0], keep[-1]

    def counter(m: Any, name: str) -> float:
        names = list(m.counter_names)
        return float(m.counter_values[names.index(name)]) if name in names else float("nan")

    out: dict[str, Any] = {
        "windows": len(keep),
        "wall_s": wall,
        "ticks": ticks,
        "rate_hz": sum(m.ticks for m in keep[1:]) / wall,
        "cpu_share": sum(m.process_cpu_share * m.window_s for m in keep[1:]) / wall,
        "tick_cpu_median_ms": float(np.median(cpu)),
        "tick_cpu_p90_ms": float(np.percentile(cpu, 90)),
        "tick_cpu_p99_ms": float(np.percentile(cpu, 99)),
        "tick_cpu_max_ms": float(cpu.max()),
        "tick_cpu_mean_ms": float(cpu.mean()),
        "tick_median_ms": float(np.median(exe)),
        "tick_p99_ms": float(np.percentile(exe, 99)),
        "tick_max_ms": float(exe.max()),
        "late_median_ms": float(np.median(late)),
        "late_p99_ms": float(np.percentile(late, 99)),
        "deadline_misses": sum(m.deadline_misses for m in keep),
        "deadline_miss_ratio": sum(m.deadline_misses for m in keep) / max(ticks, 1),
        "overruns": int(last.overruns_total - first.overruns_total),
        "stale_skipped": int(last.stale_skipped_total - first.stale_skipped_total),
        "decode_errors": int(last.decode_errors_total - first.decode_errors_total),
        **({"input_age_median_ms": float(np.median(age)),  # message-driven: response time
            "input_age_p99_ms": float(np.percentile(age, 99))} if age.size else {}),
        "_first": first,
        "_last": last,
        "_counter": counter,
    }
    return out


#: the table rows (label, figure key) of ``loop_figures``' per-tick figures, first in every
#: live benchmark's table
LOOP_ROWS = (
    ("CPU share of a core", "cpu_share"),
    ("tick CPU median (ms)", "tick_cpu_median_ms"),
    ("tick CPU p90 (ms)", "tick_cpu_p90_ms"),
    ("tick CPU p99 (ms)", "tick_cpu_p99_ms"),
    ("tick wall median (ms)", "tick_median_ms"),
    ("tick wall p99 (ms)", "tick_p99_ms"),
)


def public(fig: dict[str, Any]) -> dict[str, Any]:
    """The figures without the private helpers ``loop_figures`` keeps for its callers."""
    return {k: v for k, v in fig.items() if not k.startswith("_")}


def merge_runs(runs: list[dict[str, Any]]) -> dict[str, Any]:
    """Figures of several runs of one variant: medians of the per-run figures, except the
    tails (max of the per-run p99/max), the counts (summed) and their ratios (pooled)."""
    runs = [public(r) for r in runs if r.get("windows", 0) >= 2]
    if not runs:
        return {}
    out: dict[str, Any] = {"runs": len(runs)}
    for k in runs[0]:
        vals = [r[k] for r in runs if isinstance(r.get(k), (int, float))]
        if not vals:
            continue
        if k in ("ticks", "windows", "wall_s", "overruns", "stale_skipped", "decode_errors",
                 "lost_slots", "catch_up_steps", "sim_overruns", "packets_lost_by_peer",
                 "sink_received", "feeder_published", "peer_received", "lost", "packets_sent",
                 "watchdog_trips", "clamps", "nan_rejects", "deadline_misses"):
            out[k] = sum(vals)
        elif k.endswith(("_max_ms", "_p99_ms")):
            out[k] = max(vals)
        else:
            out[k] = float(np.median(vals))
    # ratios of the pooled counts
    out["deadline_miss_ratio"] = out.get("deadline_misses", 0) / max(out["ticks"], 1)
    if "overrun_ratio" in out:
        out["overrun_ratio"] = out["overruns"] / max(out["overruns"] + out["ticks"], 1)
    return out


def side_by_side_rows(base: dict[str, Any], this: dict[str, Any], rows: Sequence[tuple[str, str]]
                      ) -> list[tuple[str, str]]:
    """``label: baseline -> this (ratio)`` for each (label, figure key) present in both."""
    out = []
    for label, key in rows:
        a, b = base.get(key), this.get(key)
        if not isinstance(a, (int, float)) or not isinstance(b, (int, float)):
            continue
        ratio = f"  ({b / a:.2f}x)" if a else ""
        out.append((label, f"{a:.4g} -> {b:.4g}{ratio}"))
    return out


def run_interleaved(base_tree: Path | None, repeats: int,
                    run_once: Callable[[Path | None], dict[str, Any]],
                    progress: Callable[[dict[str, Any]], str],
                    ) -> tuple[dict[str, dict[str, Any]], dict[str, float], dict[str, float]]:
    """``repeats`` rounds of one run per tree (the baseline first, when there is one, then
    this tree), so both see the same machine; returns the merged figures per tree and the
    machine's load before and after."""
    variants: list[tuple[str, Path | None]] = [("this", None)]
    if base_tree is not None:
        variants.insert(0, ("baseline", base_tree))
    load0 = machine_load()
    runs: dict[str, list[dict[str, Any]]] = {name: [] for name, _ in variants}
    # a step per run, drawn between runs only: nothing of this process moves while one runs
    with progress_bar(repeats * len(variants), "runs", unit="run") as bar:
        for k in range(repeats):
            for name, tree in variants:
                fig = run_once(tree)
                runs[name].append(fig)
                say(f"run {k + 1}/{repeats} {name}: CPU share {fig['cpu_share']:.3f}, tick "
                    f"CPU median {fig['tick_cpu_median_ms'] * 1e3:.1f} us, p99 "
                    f"{fig['tick_cpu_p99_ms'] * 1e3:.1f} us, {progress(fig)}")
                bar.update(1)
    load1 = machine_load()
    return {name: merge_runs(r) for name, r in runs.items()}, load0, load1


def report_interleaved(bench: str, title: str, args: argparse.Namespace,
                       figures: dict[str, Any], merged: dict[str, dict[str, Any]],
                       loads: tuple[dict[str, float], dict[str, float]],
                       rows: Sequence[tuple[str, str]], extra: list[tuple[str, Any]]) -> int:
    """Print this tree's figures (``rows`` and ``extra``), the side by side with the baseline
    and its ratios, and write them all (flat, the baseline's prefixed) to ``args.json``."""
    load0, load1 = loads
    figures.update({
        "seconds_per_run": args.seconds,
        "repeats": args.repeats,
        "load_avg_1min_before": load0["load_avg_1min"],
        "load_avg_1min_after": load1["load_avg_1min"],
        "ref_numpy_op_us": max(load0["ref_numpy_op_us"], load1["ref_numpy_op_us"]),
    })
    for name, fig in merged.items():
        prefix = "" if name == "this" else "baseline_"
        figures.update({f"{prefix}{k}": v for k, v in fig.items()})
    this = merged["this"]
    print_table(title, [(label, this.get(key)) for label, key in rows if key in this] + extra + [
        ("load average before / after",
         f"{load0['load_avg_1min']:.2f} / {load1['load_avg_1min']:.2f}"),
        ("tiny numpy op (us)", figures["ref_numpy_op_us"])])
    if args.baseline:
        figures["baseline_rev"] = args.baseline
        for key in ("cpu_share", "tick_cpu_median_ms", "tick_cpu_p99_ms"):
            if key in this and key in merged["baseline"]:
                figures[f"{key.removesuffix('_ms')}_ratio"] = this[key] / merged["baseline"][key]
        print_table(f"side by side: baseline {args.baseline} -> this tree ({args.repeats} "
                    "interleaved runs each)", side_by_side_rows(merged["baseline"], this, rows))
    write_json(args.json, bench, figures)
    return 0


def start_child(role_args: list[str], env: dict[str, str], module: str) -> subprocess.Popen[str]:
    """``python -m module ROLE_ARGS`` as a child of this benchmark: stdout piped (a few
    lines), stderr into a temporary file (a log the child writes never blocks it)."""
    err = tempfile.TemporaryFile(mode="w+")  # noqa: SIM115 (closed by stop_child)
    p = subprocess.Popen([sys.executable, "-m", module, *role_args], cwd=REPO, env=env,
                         stdout=subprocess.PIPE, stderr=err, text=True)
    p.stderr_file = err  # type: ignore[attr-defined]
    return p


def stop_child(p: subprocess.Popen[str], timeout_s: float = 5.0) -> tuple[str, str]:
    """SIGTERM (if still running), then SIGKILL after ``timeout_s``; returns its stdout and
    stderr."""
    if p.poll() is None:
        p.send_signal(signal.SIGTERM)
    try:
        out, _ = p.communicate(timeout=timeout_s)
    except subprocess.TimeoutExpired:
        p.kill()
        out, _ = p.communicate()
    err = p.stderr_file  # type: ignore[attr-defined]
    err.seek(0)
    text = err.read()
    err.close()
    return out or "", text


def child_env(url: str) -> dict[str, str]:
    env = dict(os.environ)
    env["CASSIE_LCM_URL"] = url
    # where the model is, for a baseline revision's loader too (it reads only the variable);
    # imported here: a benchmark's child must import runtime from its own tree (use_tree)
    from runtime.robot import menagerie_root

    if (root := menagerie_root()) is not None:
        env.setdefault("MENAGERIE_ROOT", str(root))
    env["PYTHONPATH"] = os.pathsep.join([str(REPO), env.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    return env


def contend(mb: float, cpus: list[int]) -> int:
    """A stand-in for the other work on a CPU (the laptop's solvers share the target PC's CPU
    in ``hw_config/hosts.yaml``): at nice 19 on ``cpus``, sweep ``mb`` MB of memory over and
    over, so every tick of a loop there starts with caches the sweep has evicted, as it does
    in the running stack. Preempted at once by a SCHED_FIFO loop; runs until SIGTERM."""
    pin(cpus, None)
    os.nice(19)
    a = np.ones(max(1, int(mb * 2**20 / 8)))
    stop = until_sigterm()
    while not stop.is_set():
        a.sum()
    return 0


def start_contender(mb: float, cpus: list[int], module: str) -> subprocess.Popen[str] | None:
    """``contend`` in a child process (None when ``mb`` is 0)."""
    if mb <= 0:
        return None
    p = start_child(["--role", "contend", "--mb", str(mb), "--cpus", ",".join(map(str, cpus))],
                    dict(os.environ), module)
    assert p.stdout is not None
    p.stdout.readline()
    return p


def run_live(tree: str | None, name: str, seconds: float, udp_ports: dict[str, int],
             params: dict[str, Any] | None = None) -> int:
    """A benchmark's child: the process ``name`` of ``tree``'s ``hw_config/sim.yaml`` (None:
    this one's) under the live runner for ``seconds``, scheduled as ``cassie run`` does, each
    role of ``udp_ports`` moved to UDP on 127.0.0.1 at that port, ``params`` laid over its
    own."""
    root = use_tree(tree)
    import importlib
    import logging

    from runtime.config import load_profile
    from runtime.config_types import ChannelConfig
    from runtime.loops import LiveRunner
    from runtime.scheduling import apply_scheduling

    logging.basicConfig(level=logging.WARNING, format="%(name)s %(levelname)s: %(message)s")
    profile = load_profile(root / "hw_config" / "sim.yaml")
    proc = profile.processes[name]

    def moved(ports: dict[str, Any]) -> dict[str, Any]:
        out = dict(ports)
        for role, port in udp_ports.items():
            if role in ports:
                out[role] = ChannelConfig(ports[role].key, f"udp:127.0.0.1:{port}",
                                          ("127.0.0.1", port))
        return out

    proc = dataclasses.replace(proc, inputs=moved(proc.inputs), outputs=moved(proc.outputs),
                               params={**proc.params, **(params or {})})
    profile = dataclasses.replace(profile, processes={**profile.processes, name: proc})
    for note in apply_scheduling(proc):
        if "failed" in note:
            print(note, file=sys.stderr)
    node = importlib.import_module("runtime.builder").build_node(proc, profile)
    return LiveRunner(node, proc, profile).run(duration_s=seconds)


def run_figures(what: str, child: subprocess.Popen[str], err: str, msgs: list[Any],
                warmup_s: float) -> tuple[dict[str, Any], Callable[[str], float]]:
    """The figures of a finished run of ``child`` (the ``what`` timed; its stderr ``err``)
    from its TIMING ``msgs`` (``loop_figures``), and ``delta(counter)``: how much one of its
    counters grew over them. SystemExit, with the end of its log, when it failed or said
    nothing after the warm-up; the lines of the log that say something failed are shown."""
    if child.returncode != 0:
        raise SystemExit(f"the {what} exited with {child.returncode}:\n{err[-3000:]}")
    fig = loop_figures(msgs, warmup_s)
    if fig.get("windows", 0) < 2:
        raise SystemExit(f"no TIMING from the {what} after the warm-up:\n{err[-3000:]}")
    c, first, last = fig.pop("_counter"), fig.pop("_first"), fig.pop("_last")
    for ln in [ln for ln in err.splitlines() if "failed" in ln or "Error" in ln][:5]:
        print(f"{what}:", ln, file=sys.stderr)
    return fig, lambda counter: c(last, counter) - c(first, counter)


def add_live_options(ap: argparse.ArgumentParser, what: str, shares: str,
                     roles: Sequence[str], extra: Callable[[], object] = lambda: None) -> None:
    """The options of a live benchmark of ``what``: figures, durations, repeats, ``extra()``'s
    own, the contender on its CPU (which ``shares`` in the stack) and the baseline; then its
    children's (hidden): ``--role`` (one of ``roles``), ``--tree``, ``--cpus``, ``--fifo``,
    ``--mb``."""
    ap.add_argument("--json", metavar="FILE", help="write the figures as one flat JSON object")
    ap.add_argument("--seconds", type=float, default=5.0,
                    help="timed seconds of each run (after the warm-up; default 5)")
    ap.add_argument("--warmup", type=float, default=1.0, help="seconds left out at the start")
    ap.add_argument("--repeats", type=int, default=2, help="runs of each variant (default 2)")
    extra()
    ap.add_argument("--contend", metavar="MB", type=float, default=8.0,
                    help=f"a nice-19 process on the {what}'s CPU sweeping MB of memory, as "
                         f"{shares} share that CPU in the stack (default 8; 0: none)")
    ap.add_argument("--baseline", metavar="REV",
                    help=f"also run the {what} of git revision REV, interleaved with this tree's")
    ap.add_argument("--role", choices=tuple(roles), help=argparse.SUPPRESS)
    ap.add_argument("--tree", help=argparse.SUPPRESS)
    ap.add_argument("--cpus", default="", help=argparse.SUPPRESS)
    ap.add_argument("--fifo", type=int, default=0, help=argparse.SUPPRESS)
    ap.add_argument("--mb", type=float, default=0.0, help=argparse.SUPPRESS)


# -- this benchmark's processes --------------------------------------------------------------


def _peer(listen_port: int, send_port: int, cpus: list[int], fifo: int,
          tree: str | None = None) -> int:
    """The NUC stand-in: answer each state packet at once with a zero-torque packet, in the
    protocol of the sim's tree (``tree``: a baseline's, which may be an older version)."""
    use_tree(tree)
    from runtime.cassie_packets import InputPacket, LinkCounter, OutputPacket, PacketError

    notes = pin(cpus, fifo)
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", listen_port))
    sock.settimeout(0.2)
    dest = ("127.0.0.1", send_port)
    state, cmd, link = OutputPacket(), InputPacket(), LinkCounter()
    buf = bytearray(2048)
    view = memoryview(buf)
    stop = until_sigterm()
    while not stop.is_set():
        try:
            n = sock.recv_into(buf)
        except (TimeoutError, InterruptedError):
            continue
        try:
            state.decode(view[:n])
        except PacketError:
            link.on_error()
            continue
        link.on_receive(state.seq, state.ack)
        try:
            sock.sendto(cmd.encode(link.next_seq(), link.last_peer_seq), dest)
        except OSError:
            pass
    print(json.dumps({"received": link.received, "lost": link.lost, "malformed": link.malformed,
                      "max_round_trip_cycles": link.max_round_trip_cycles, "notes": notes}),
          flush=True)
    return 0


def _sim(tree: str | None, out_port: int, in_port: int, seconds: float, terrain: str,
         camera: bool) -> int:
    """The sim of ``tree``'s ``hw_config/sim.yaml`` under the live runner, its UDP links moved
    to the benchmark's ports."""
    params: dict[str, Any] = {"terrain": terrain}
    if camera:
        params["camera_render"] = "process"
    return run_live(tree, "sim", seconds, {"robot_output": out_port, "command": in_port},
                    params)


def _run_once(tree: Path | None, args: argparse.Namespace, nuc_cpus: list[int],
              sim_cpus: list[int], peer_fifo: int) -> dict[str, Any]:
    """One live run of the sim of ``tree`` (None: this one) against a fresh peer."""
    url = bench_lcm_url()
    env = child_env(url)
    out_port, in_port = free_udp_port(), free_udp_port()
    mod = "tools.benchmarks.sim"
    peer = start_child(["--role", "peer", "--ports", str(out_port), str(in_port), "--cpus",
                        ",".join(map(str, nuc_cpus)), "--fifo", str(peer_fifo),
                        *(["--tree", str(tree)] if tree is not None else [])], env, mod)
    assert peer.stdout is not None
    if peer.stdout.readline().strip() != "ready":
        raise SystemExit(f"the peer did not start: {stop_child(peer)[1]}")
    cmd = ["--role", "sim", "--ports", str(out_port), str(in_port), "--seconds",
           str(args.seconds + args.warmup), "--terrain", args.terrain]
    if tree is not None:
        cmd += ["--tree", str(tree)]
    if args.camera:
        cmd.append("--camera")
    hog = start_contender(args.contend, sim_cpus, mod)
    sim = start_child(cmd, env, mod)
    try:
        msgs = collect_timing(sim, url, "sim", args.seconds + args.warmup + 120.0)
        sim.wait(timeout=30.0)
    finally:
        _, sim_err = stop_child(sim)
        peer_out, peer_err = stop_child(peer)
        if hog is not None:
            stop_child(hog)
    fig, delta = run_figures("sim", sim, sim_err, msgs, args.warmup)
    fig["realtime_factor"] = delta("sim_time_s") / fig["wall_s"]
    for name, key in (("lost_slots", "lost_slots"), ("catch_up_steps", "catch_up_steps"),
                      ("overruns", "sim_overruns")):
        fig[key] = int(delta(name))
    fig["overrun_ratio"] = fig["overruns"] / max(fig["overruns"] + fig["ticks"], 1)
    try:
        pr = json.loads(peer_out.strip().splitlines()[-1])
        fig["packets_lost_by_peer"] = int(delta("commands_lost"))
        fig["peer_received"] = pr["received"]
        fig["round_trip_max_cycles"] = pr["max_round_trip_cycles"]
        if pr["notes"]:
            print("peer:", "; ".join(pr["notes"]), file=sys.stderr)
    except (ValueError, IndexError, KeyError):
        print(f"peer: no summary ({peer_err.strip()[-500:]})", file=sys.stderr)
    return fig


ROWS = (
    *LOOP_ROWS,
    ("start lateness p99 (ms)", "late_p99_ms"),
    ("real-time factor", "realtime_factor"),
    ("slots skipped (overruns)", "overruns"),
    ("overrun ratio", "overrun_ratio"),
    ("deadline miss ratio", "deadline_miss_ratio"),
    ("ticks", "ticks"),
)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="cassie bench sim", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)

    def sim_options() -> None:
        ap.add_argument("--terrain", default="flat", help="terrain (default: flat, as sim.yaml)")
        ap.add_argument("--camera", action="store_true",
                        help="with the depth camera rendering in its child process (sim.yaml "
                             "turns it off)")

    add_live_options(ap, "sim", "the laptop's solvers", ("peer", "sim", "contend"), sim_options)
    ap.add_argument("--ports", type=int, nargs=2, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.role == "peer":
        return _peer(*args.ports, [int(c) for c in args.cpus.split(",") if c], args.fifo,
                     args.tree)
    if args.role == "contend":
        return contend(args.mb, [int(c) for c in args.cpus.split(",") if c])
    if args.role == "sim":
        return _sim(args.tree, *args.ports, args.seconds, args.terrain, args.camera)

    from runtime.config import load_profile

    profile = load_profile(REPO / "hw_config" / "sim.yaml")
    est = profile.processes["state_estimator"]
    nuc_cpus = list(est.cpu_affinity or ())
    sim_cpus = list(profile.processes["sim"].cpu_affinity or ())
    pin(nuc_cpus, None)  # this process reads TIMING on the NUC's CPU, away from the sim's
    base_tree = extract_tree(args.baseline, SIM_TREE) if args.baseline else None
    merged, load0, load1 = run_interleaved(
        base_tree, args.repeats,
        lambda tree: _run_once(tree, args, nuc_cpus, sim_cpus, est.rt_priority or 0),
        lambda fig: f"rtf {fig['realtime_factor']:.3f}")
    figures: dict[str, Any] = {
        "description": f"sim of hw_config/sim.yaml under LiveRunner (CPU {sim_cpus}, SCHED_FIFO "
                       f"{profile.processes['sim'].rt_priority}), peer process answering each "
                       f"state (CPU {nuc_cpus}); {args.terrain}, camera "
                       f"{'on' if args.camera else 'off'}; contender sweeping "
                       f"{args.contend:g} MB on the sim's CPU; {args.repeats} x "
                       f"{args.seconds:g} s",
        "terrain": args.terrain,
        "camera": args.camera,
        "contend_mb": args.contend,
    }
    this = merged["this"]
    return report_interleaved(
        "sim", "sim at 2 kHz under LiveRunner (this tree)", args, figures, merged,
        (load0, load1), ROWS,
        [("packets lost (peer -> sim)", this.get("packets_lost_by_peer")),
         ("round trip max (cycles)", this.get("round_trip_max_cycles"))])


if __name__ == "__main__":
    raise SystemExit(main())
