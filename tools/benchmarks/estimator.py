"""``cassie bench estimator``: the state estimator's tick time and its error against ground truth.

1. A scripted run of the real MuJoCo sim in the deterministic harness (sim -> estimator ->
   scripted joint PD -> torque bridge -> sim; ``tools.testbed.estimator_motions``), with the
   sim's ground truth at every state: velocity RMSE, position error and drift per metre of
   pelvis path, contact agreement.
2. The run's raw robot-output packets replayed through a fresh estimator node, one tick per
   packet as live (decode, range checks, estimate, fill and encode the three LCM messages), with
   the garbage collector frozen like the live loops: tick time median, p99, max and the
   fraction of ticks over the 0.5 ms packet period.
3. ``--live``: the same packets fed live, in the conditions of the real stack: the estimator
   node under ``runtime.loops.LiveRunner`` in a process of its own (pinned to the NUC's CPU 1,
   SCHED_FIFO, as ``hw_config/sim.yaml`` runs it), a replayer process on CPU 0 (the target PC)
   sending the packets over real UDP at 2 kHz on an absolute schedule, and two subscriber
   processes on CPU 1 blocked on the estimator's CASSIE_STATE (as the OSC and the torque
   bridge are). On this VM every wake-up after idle runs with cold caches, so a live tick costs
   3-4x the hot loop's. Figures from the estimator's own TIMING messages: its process CPU
   share of a core (process CPU seconds / wall seconds), the thread CPU of a tick (median,
   p99) and the CPU it spends per packet outside its ticks (runner loop, wake-up, receive).
   With ``--baseline REV`` the baseline's estimator runs beside this tree's, in interleaved
   segments of the same run (each estimator fed its own continuous packet stream).
"""

from __future__ import annotations

import argparse
import gc
import time
from pathlib import Path
from typing import Any

import numpy as np

from runtime.driver import NodeDriver
from tools.benchmarks.common import (
    REPO,
    free_udp_port,
    git_archive,
    machine_load,
    print_table,
    progress,
    summarize,
    write_json,
)

PERIOD_MS = 0.5


def time_ticks(packets: list[bytes], repeats: int = 1, node_cls: type | None = None,
               desc: str = "timed ticks") -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Tick a fresh estimator node on every packet; returns the node tick's wall time, its
    thread CPU time (the work itself, without preemption), and the update-only wall time, ms.
    ``node_cls``: the node class to time (default: this tree's ``StateEstimatorNode``);
    ``desc`` names the progress bar."""
    if node_cls is None:
        from processes.state_estimator.process import StateEstimatorNode as node_cls

    node_ms: list[float] = []
    cpu_ms: list[float] = []
    upd_ms: list[float] = []
    # each packet twice: the node's tick, then the estimator's update alone
    bar = progress(2 * repeats * len(packets), desc, unit="tick")
    for _ in range(repeats):
        # every message encoded as LCM would send it, none decimated, none decoded
        d = NodeDriver(node_cls(), encoded=True)
        node = d.node
        est = node.estimator
        assert est is not None
        gc.collect()
        gc.freeze()
        gc.disable()
        try:
            for raw in packets:
                # the driver times node.tick alone (tick_ns): this put and its taking of
                # the trigger are left out
                d.put("robot_output", raw)
                d.tick()
                node_ms.append(d.tick_ns / 1e6)
                cpu_ms.append(d.tick_cpu_ns / 1e6)
                for sent in d.sent.values():
                    sent.clear()  # (nothing kept, as LCM keeps nothing)
                bar.update(1)  # outside the timed tick
            # the estimator alone (no packet decode, no messages), on the decoded packets,
            # with the ALIP part on every network_every-th packet as in the node
            est2 = type(est)(node.params, est.kin.m)
            pkt, every = node.pkt, node.params.network_every
            for i, raw in enumerate(packets):
                pkt.decode(raw)
                t0 = time.perf_counter_ns()
                est2.update(pkt, alip=i % every == 0)
                upd_ms.append((time.perf_counter_ns() - t0) / 1e6)
                bar.update(1)
        finally:
            gc.enable()
            gc.unfreeze()
    bar.close()
    return np.array(node_ms), np.array(cpu_ms), np.array(upd_ms)


def baseline_root(rev: str) -> Path:
    """A folder holding ``processes/state_estimator`` of git revision ``rev`` as package
    ``baseline_state_estimator`` (one folder per commit, reused by later runs, so numba's
    on-disk cache of its kernels survives from one bench run to the next)."""
    import io
    import os
    import tarfile
    import tempfile

    sha, tar = git_archive(rev, ("processes/state_estimator",))
    root = Path(tempfile.gettempdir()) / f"estimator-baseline-{sha}"
    if not (root / "baseline_state_estimator" / ".complete").exists():
        tmp = Path(tempfile.mkdtemp(prefix=f"estimator-baseline-{sha[:12]}-"))
        with tarfile.open(fileobj=io.BytesIO(tar)) as tf:
            tf.extractall(tmp, filter="data")
        (tmp / "processes" / "state_estimator").rename(tmp / "baseline_state_estimator")
        (tmp / "baseline_state_estimator" / ".complete").touch()
        try:
            os.rename(tmp, root)
        except OSError:  # another run extracted it meanwhile (or a stale folder): use ours
            root = tmp
    return root


def baseline_node(rev: str) -> type:
    """The ``StateEstimatorNode`` of git revision ``rev`` of ``processes/state_estimator``,
    imported beside this tree's as package ``baseline_state_estimator`` (its imports of
    ``runtime``/``lcmtypes`` resolve to this tree's: a baseline for the estimator's own code)."""
    import importlib
    import sys

    root = baseline_root(rev)
    pkg = "baseline_state_estimator"
    loaded = sys.modules.get(pkg)
    if loaded is not None and Path(loaded.__file__ or "").parent.parent != root:
        # another revision's baseline was imported in this process: forget it
        for name in [n for n in sys.modules if n == pkg or n.startswith(pkg + ".")]:
            del sys.modules[name]
    if str(root) in sys.path:
        sys.path.remove(str(root))
    sys.path.insert(0, str(root))
    return importlib.import_module(f"{pkg}.process").StateEstimatorNode


def side_by_side(packets: list[bytes], baseline: type, repeats: int = 3) -> dict[str, float]:
    """Node tick time of ``baseline`` and of this tree's node on the same packets, in
    interleaved repeats (so both see the same machine load); figures and ratios."""
    from processes.state_estimator.process import StateEstimatorNode

    runs: dict[str, list[np.ndarray]] = {"baseline": [], "this": []}
    for k in range(repeats):
        runs["baseline"].append(time_ticks(packets, node_cls=baseline,
                                           desc=f"baseline {k + 1}/{repeats}")[0])
        runs["this"].append(time_ticks(packets, node_cls=StateEstimatorNode,
                                       desc=f"this tree {k + 1}/{repeats}")[0])
    out: dict[str, float] = {"side_by_side_repeats": repeats}
    for name, parts in runs.items():
        a = np.concatenate(parts)
        out[f"{name}_tick_p10_ms"] = float(np.percentile(a, 10))
        out[f"{name}_tick_median_ms"] = float(np.median(a))
        out[f"{name}_tick_p99_ms"] = float(np.percentile(a, 99))
        out[f"{name}_tick_max_ms"] = float(a.max())
        out[f"{name}_tick_over_period_ratio"] = float((a > PERIOD_MS).mean())
    for k in ("p10", "median", "p99"):
        out[f"speedup_{k}_ratio"] = out[f"baseline_tick_{k}_ms"] / out[f"this_tick_{k}_ms"]
    return out


# -- live: the node under LiveRunner, fed over real UDP at 2 kHz ------------------------------
LIVE_PROFILE = REPO / "hw_config" / "sim.yaml"
#: the subscribers of CASSIE_STATE, each with the CPU and SCHED_FIFO priority of the process it
#: stands in for (both on the NUC's CPU, below the estimator's priority)
LIVE_SUBSCRIBERS = ("osc", "torque_bridge")
LIVE_WARMUP_S = 0.3  # of each segment, left out (the first TIMING window spans the idle gap)


def _live_profile() -> Any:
    from runtime.config import load_profile

    return load_profile(LIVE_PROFILE)  # the LCM port from CASSIE_LCM_URL (set by the parent)


def _rt_notes(notes: list[str]) -> None:
    import sys

    for note in notes:
        if "failed" in note:
            print(f"live bench: {note}", file=sys.stderr)


def _child_estimator(name: str, port: int, root: str) -> int:
    """An estimator process as ``cassie run state_estimator`` starts it, its UDP input on
    ``port``; ``root``: a ``baseline_root`` folder (the baseline's node), "" for this tree's."""
    import dataclasses
    import importlib
    import sys

    from runtime.loops import LiveRunner
    from runtime.scheduling import apply_scheduling

    profile = _live_profile()
    proc = profile.processes["state_estimator"]
    rx = dataclasses.replace(proc.inputs["robot_output"], name=f"udp:127.0.0.1:{port}",
                             udp=("127.0.0.1", port))
    proc = dataclasses.replace(proc, name=name, inputs={**proc.inputs, "robot_output": rx})
    _rt_notes(apply_scheduling(proc))  # the NUC's CPU; SCHED_FIFO once set up (LiveRunner)
    if root:
        sys.path.insert(0, root)
        module = importlib.import_module("baseline_state_estimator.process")
    else:
        module = importlib.import_module("processes.state_estimator.process")
    node = importlib.import_module("runtime.builder").build_node(proc, profile, module)
    return LiveRunner(node, proc, profile).run()


def _child_subscriber(like: str) -> int:
    """Blocked on CASSIE_STATE, decoding the newest state on every wake-up (as the OSC does),
    with the CPU and real-time priority of process ``like``; prints what it received."""
    import json
    import select
    import signal
    import sys

    from lcmtypes import robot_state_t
    from runtime.bus import Bus
    from runtime.scheduling import apply_scheduling

    profile = _live_profile()
    proc = profile.processes[like]
    _rt_notes(apply_scheduling(proc))
    bus = Bus.for_profile(profile, source=f"bench-{like}")
    sub = bus.subscribe(profile.channels["state"].name, robot_state_t, "newest", wake=True)
    poller = select.poll()
    for fd in bus.filenos():
        poller.register(fd, select.POLLIN)
    stop = [False]
    signal.signal(signal.SIGTERM, lambda *_: stop.__setitem__(0, True))
    gc.collect()
    gc.freeze()
    gc.disable()
    _rt_notes(apply_scheduling(proc, realtime=True))
    print("ready", flush=True)
    decoded = 0
    while not stop[0]:
        try:
            poller.poll(50)
        except InterruptedError:
            continue
        bus.handle_pending()
        if sub.fresh and sub.latest() is not None:
            decoded += 1
    json.dump({"received": sub.received, "decoded": decoded}, sys.stdout)
    return 0


def _child_replayer(packets_file: str, schedule: str, gap_s: float) -> int:
    """The target PC: send the recorded packets over UDP at 2 kHz on an absolute schedule, in
    segments ``PORT:SECONDS,...``; each port gets its own continuous stream (utime +500 us and
    seq +1 per packet it receives; the recording repeats). Prints the segments' start and end
    (CLOCK_MONOTONIC) and send lateness as JSON."""
    import json
    import os
    import socket
    import struct
    import sys

    from runtime.loops import _set_timer_slack_ns

    os.sched_setaffinity(0, {0})  # the target PC's CPU (hw_config/hosts.yaml)
    sim = _live_profile().processes["sim"]
    _rt_notes(apply_rt(sim.rt_priority))
    _set_timer_slack_ns(1000)
    rows = np.load(packets_file)
    bufs = [bytearray(r.tobytes()) for r in rows]
    utime0 = struct.unpack_from("<q", bufs[0], 4)[0]
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sent: dict[int, int] = {}
    marks = []
    mono = time.monotonic_ns
    for item in schedule.split(","):
        port_s, sec_s = item.split(":")
        port, n = int(port_s), round(float(sec_s) * 2000)
        k0 = sent.get(port, 0)
        addr = ("127.0.0.1", port)
        late = np.zeros(n)
        t0 = mono() + 2_000_000
        for i in range(n):
            t = t0 + i * 500_000
            w = t - mono()
            if w > 0:
                time.sleep(w / 1e9)
            k = k0 + i
            b = bufs[k % len(bufs)]
            struct.pack_into("<q", b, 4, utime0 + 500 * k)
            b[0] = k & 0xFF
            late[i] = mono() - t
            sock.sendto(b, addr)
        end = mono()
        sent[port] = k0 + n
        marks.append({"port": port, "start_ns": t0, "end_ns": end, "packets": n,
                      "late_p99_us": float(np.percentile(late, 99)) / 1e3,
                      "late_max_us": float(late.max()) / 1e3})
        time.sleep(gap_s)
    json.dump(marks, sys.stdout)
    return 0


def apply_rt(prio: int | None) -> list[str]:
    """SCHED_FIFO ``prio`` for this process (``runtime.scheduling``), best effort."""
    from runtime.scheduling import apply_scheduling

    class _P:
        rt_priority = prio

    return apply_scheduling(_P(), realtime=True)


def _live_child(argv: list[str]) -> int:
    role, *rest = argv
    if role == "estimator":
        return _child_estimator(rest[0], int(rest[1]), rest[2] if len(rest) > 2 else "")
    if role == "subscriber":
        return _child_subscriber(rest[0])
    if role == "replayer":
        return _child_replayer(rest[0], rest[1], float(rest[2]))
    raise SystemExit(f"unknown live role {role!r}")


def live_run(packets: list[bytes], variants: dict[str, Path | None], seconds: float = 3.0,
             repeats: int = 3, gap_s: float = 0.4) -> dict[str, Any]:
    """Run each variant's estimator live (``variants``: name -> ``baseline_root`` folder, or
    None for this tree), fed in turn ``repeats`` times for ``seconds`` each (interleaved);
    returns per-segment figures and, per variant, their summary."""
    import json
    import os
    import random
    import signal
    import subprocess
    import sys
    import tempfile

    import psutil

    from lcmtypes import loop_timing_t
    from runtime.bus import Bus

    url = f"udpm://239.255.76.67:{random.randint(20000, 60000)}"
    env = dict(os.environ, CASSIE_LCM_URL=url, PYTHONPATH=os.pathsep.join(
        [str(REPO), os.environ.get("PYTHONPATH", "")]).rstrip(os.pathsep))
    old_url = os.environ.get("CASSIE_LCM_URL")
    os.environ["CASSIE_LCM_URL"] = url
    old_aff = os.sched_getaffinity(0)
    os.sched_setaffinity(0, {0})  # the bench itself stays off the NUC's CPU
    work = Path(tempfile.mkdtemp(prefix="estimator-live-"))
    np.save(work / "packets.npy", np.array([np.frombuffer(p, np.uint8) for p in packets]))
    me = [sys.executable, "-m", "tools.benchmarks.estimator", "_live_child"]
    kids: dict[str, subprocess.Popen[str]] = {}
    logs = []

    def spawn(key: str, *args: str, pipe: bool = False) -> subprocess.Popen[str]:
        log = open(work / f"{key}.log", "w")  # noqa: SIM115 - closed at the end
        logs.append(log)
        p = subprocess.Popen([*me, *args], cwd=REPO, env=env, text=True,
                             stdout=subprocess.PIPE if pipe else log, stderr=log)
        kids[key] = p
        return p

    ports = {v: free_udp_port() for v in variants}
    names = {v: f"state_estimator_{v}" for v in variants}
    try:
        bus = Bus.for_profile(_live_profile(), source="bench")
        timing = bus.subscribe("TIMING", loop_timing_t, "each", capacity=1 << 20)
        for v, root in variants.items():
            spawn(v, "estimator", names[v], str(ports[v]), str(root or ""))
        subs = [spawn(f"sub_{like}", "subscriber", like, pipe=True) for like in LIVE_SUBSCRIBERS]
        msgs: list[Any] = []

        def collect() -> None:
            while (m := timing.pop()) is not None:
                msgs.append(m)

        ready: set[str] = set()
        end = time.monotonic() + 180.0  # a baseline's first start compiles its kernels
        while ready != set(names.values()):
            bus.poll_every(0.1)
            collect()
            ready |= {m.process for m in msgs} & set(names.values())
            dead = [k for k, p in kids.items() if p.poll() is not None]
            if dead or time.monotonic() > end:
                raise RuntimeError(f"live bench: {dead or 'estimators'} did not start; logs in "
                                   f"{work}")
        for p in subs:
            assert p.stdout is not None
            if p.stdout.readline().strip() != "ready":
                raise RuntimeError(f"live bench: a subscriber did not start; logs in {work}")
        order = [v for _ in range(repeats) for v in variants]
        schedule = ",".join(f"{ports[v]}:{seconds:g}" for v in order)
        rep = spawn("replayer", "replayer", str(work / "packets.npy"), schedule, str(gap_s),
                    pipe=True)
        procs = {k: psutil.Process(p.pid) for k, p in kids.items() if k != "replayer"}
        cpu_samples: list[tuple[int, dict[str, float]]] = []
        # the replayer's schedule in wall seconds: this process (on CPU 0, off the
        # estimators') already wakes every 0.1 s here; a redraw at most every 0.5 s
        bar = progress(round(len(order) * (seconds + gap_s), 1), "live segments", unit="s",
                       bar_format="{l_bar}{bar}| {n:.0f}/{total:.0f} s [{elapsed}<{remaining}]")
        t_last = time.monotonic()
        while rep.poll() is None:
            bus.poll_every(0.1)
            collect()
            t = time.monotonic_ns()
            cpu_samples.append((t, {k: sum(pr.cpu_times()[:2]) for k, pr in procs.items()}))
            bar.update(t / 1e9 - t_last)
            t_last = t / 1e9
        bar.close()
        if rep.returncode != 0:
            raise RuntimeError(f"live bench: the replayer failed; logs in {work}")
        assert rep.stdout is not None
        marks = json.loads(rep.stdout.read())
        bus.poll_every(0.3)
        collect()
        for p in kids.values():
            if p.poll() is None:
                p.send_signal(signal.SIGTERM)
        sub_out = []
        for p in subs:
            out, _ = p.communicate(timeout=10)
            sub_out.append(json.loads(out.strip().splitlines()[-1]) if out.strip() else {})
        for p in kids.values():
            p.wait(timeout=10)
        bus.close()
    finally:
        for p in kids.values():
            if p.poll() is None:
                p.kill()
                p.wait()
        for log in logs:
            log.close()
        os.sched_setaffinity(0, old_aff)
        if old_url is None:
            os.environ.pop("CASSIE_LCM_URL", None)
        else:
            os.environ["CASSIE_LCM_URL"] = old_url
    by_port = {ports[v]: v for v in variants}
    segments = []
    for mk in marks:
        v = by_port[mk["port"]]
        seg = _live_segment(v, names[v], mk, msgs, cpu_samples)
        segments.append(seg)
    out: dict[str, Any] = {"segments": segments, "subscribers": sub_out, "work_dir": str(work)}
    for v in variants:
        last = [m for m in msgs if m.process == names[v]][-1]
        counters = dict(zip(last.counter_names, last.counter_values, strict=True))
        out[v] = _live_summary([s for s in segments if s["variant"] == v], counters,
                               last.stale_skipped_total)
    import shutil

    shutil.rmtree(work, ignore_errors=True)
    return out


def _live_segment(variant: str, name: str, mark: dict[str, Any], msgs: list[Any],
                  cpu_samples: list[tuple[int, dict[str, float]]]) -> dict[str, Any]:
    """The figures of one segment from the TIMING messages published inside it."""
    lo = mark["start_ns"] + int(LIVE_WARMUP_S * 1e9)
    hi = mark["end_ns"]
    win = [m for m in msgs if m.process == name and lo <= m.header.send_mono_ns <= hi]
    seg: dict[str, Any] = {"variant": variant, "late_p99_us": mark["late_p99_us"],
                           "late_max_us": mark["late_max_us"]}
    if len(win) < 2:
        return seg
    r0, r1 = win[0], win[-1]
    wall = (r1.header.send_mono_ns - r0.header.send_mono_ns) / 1e9
    cpu_s = r1.process_cpu_s - r0.process_cpu_s
    inner = win[1:]
    tick_cpu = np.concatenate([np.asarray(m.cpu_ms, dtype=float) for m in inner])
    tick_exec = np.concatenate([np.asarray(m.exec_ms, dtype=float) for m in inner])
    ticks = sum(m.ticks for m in inner)
    seg.update({
        "wall_s": wall, "ticks": ticks, "rate_hz": ticks / wall, "cpu_share": cpu_s / wall,
        "tick_cpu_ms": tick_cpu, "tick_exec_ms": tick_exec,
        # process CPU per packet beyond its tick: runner loop, poll wake-up, UDP receive, TIMING
        "outside_tick_us": (cpu_s * 1e3 - tick_cpu.sum()) * 1e3 / max(ticks, 1),
    })
    ps = [(t, c) for t, c in cpu_samples if lo <= t <= hi]
    if len(ps) >= 2:
        (t0, c0), (t1, c1) = ps[0], ps[-1]
        dt = (t1 - t0) / 1e9
        seg["psutil_cpu_share"] = (c1[variant] - c0[variant]) / dt
        seg["subscribers_cpu_share"] = sum(c1[k] - c0[k] for k in c1
                                           if k.startswith("sub_")) / dt
    return seg


def _live_summary(segs: list[dict[str, Any]], counters: dict[str, float],
                  stale: int) -> dict[str, float]:
    """One variant's figures over its segments: medians of the per-segment shares, percentiles
    of the pooled per-tick samples."""
    good = [s for s in segs if "cpu_share" in s]
    if not good:
        return {"segments": 0}
    cpu = np.concatenate([s["tick_cpu_ms"] for s in good])
    ex = np.concatenate([s["tick_exec_ms"] for s in good])
    shares = [s["cpu_share"] for s in good]
    return {
        "segments": len(good),
        "cpu_share_median": float(np.median(shares)),
        "cpu_share_min": float(min(shares)),
        "cpu_share_max": float(max(shares)),
        "psutil_cpu_share_median": float(np.median([s.get("psutil_cpu_share", np.nan)
                                                    for s in good])),
        "ticks": int(sum(s["ticks"] for s in good)),
        "rate_hz_median": float(np.median([s["rate_hz"] for s in good])),
        "tick_cpu_median_ms": float(np.median(cpu)),
        "tick_cpu_p90_ms": float(np.percentile(cpu, 90)),
        "tick_cpu_p99_ms": float(np.percentile(cpu, 99)),
        "tick_exec_median_ms": float(np.median(ex)),
        "tick_exec_p99_ms": float(np.percentile(ex, 99)),
        "tick_over_period_ratio": float((ex > PERIOD_MS).mean()),
        "outside_tick_cpu_per_packet_us": float(np.median([s["outside_tick_us"] for s in good])),
        "subscribers_cpu_share_median": float(np.median([s.get("subscribers_cpu_share", np.nan)
                                                         for s in good])),
        "send_late_p99_us_max": float(max(s["late_p99_us"] for s in segs)),
        "packets_received": counters.get("packets_received", 0.0),
        "packets_rejected": counters.get("packets_rejected", 0.0),
        "packets_lost": counters.get("packets_lost", 0.0),
        "estimator_resets": counters.get("estimator_resets", 0.0),
        "stale_skipped": float(stale),
    }


def live_figures(live: dict[str, Any], variants: list[str]) -> dict[str, float]:
    """Flat JSON figures of ``live_run`` (names carry their unit) and ratios to the baseline."""
    units = {"cpu_share_median": "cores", "cpu_share_min": "cores", "cpu_share_max": "cores",
             "psutil_cpu_share_median": "cores", "subscribers_cpu_share_median": "cores",
             "rate_hz_median": "", "tick_over_period_ratio": "",
             "outside_tick_cpu_per_packet_us": "", "send_late_p99_us_max": "",
             "segments": "", "ticks": "", "packets_received": "", "packets_rejected": "",
             "packets_lost": "", "estimator_resets": "", "stale_skipped": ""}
    out: dict[str, float] = {}
    for v in variants:
        for k, val in live[v].items():
            unit = units.get(k, "")
            out[f"live_{v}_{k}{'_' + unit if unit else ''}"] = val
    if "baseline" in variants and "this" in variants and live["this"].get("segments"):
        b, t = live["baseline"], live["this"]
        out["live_cpu_share_reduction_ratio"] = 1.0 - t["cpu_share_median"] / b[
            "cpu_share_median"]
        out["live_tick_cpu_median_speedup_ratio"] = (b["tick_cpu_median_ms"]
                                                     / t["tick_cpu_median_ms"])
        out["live_tick_cpu_p99_speedup_ratio"] = b["tick_cpu_p99_ms"] / t["tick_cpu_p99_ms"]
    return out


def print_live(live: dict[str, Any], variants: list[str], title: str) -> None:
    """The live figures side by side (one column per variant)."""
    rows = [
        ("segments (interleaved)", "segments", "{:.0f}"),
        ("CPU share of a core, median", "cpu_share_median", "{:.3f}"),
        ("CPU share, min - max", None, None),
        ("CPU share (psutil), median", "psutil_cpu_share_median", "{:.3f}"),
        ("rate (Hz)", "rate_hz_median", "{:.0f}"),
        ("tick thread CPU median (ms)", "tick_cpu_median_ms", "{:.4f}"),
        ("tick thread CPU p90 (ms)", "tick_cpu_p90_ms", "{:.4f}"),
        ("tick thread CPU p99 (ms)", "tick_cpu_p99_ms", "{:.4f}"),
        ("tick wall median / p99 (ms)", None, None),
        ("ticks over 0.5 ms", "tick_over_period_ratio", "{:.2%}"),
        ("CPU per packet outside the tick (us)", "outside_tick_cpu_per_packet_us", "{:.1f}"),
        ("2 subscribers' CPU share", "subscribers_cpu_share_median", "{:.3f}"),
        ("packets received / rejected / lost", None, None),
        ("replayer send lateness p99 (us, worst)", "send_late_p99_us_max", "{:.0f}"),
    ]
    table = []
    for label, key, fmt in rows:
        cells = []
        for v in variants:
            f = live[v]
            if not f.get("segments"):
                cells.append("-")
            elif key is not None:
                cells.append(fmt.format(f[key]))
            elif label.startswith("CPU share, min"):
                cells.append(f"{f['cpu_share_min']:.3f} - {f['cpu_share_max']:.3f}")
            elif label.startswith("tick wall"):
                cells.append(f"{f['tick_exec_median_ms']:.4f} / {f['tick_exec_p99_ms']:.4f}")
            else:
                cells.append(f"{f['packets_received']:.0f} / {f['packets_rejected']:.0f} / "
                             f"{f['packets_lost']:.0f}")
        table.append((label, *cells))
    print_table(title, table, columns=["", *variants], justify="l" + "r" * len(variants))


def equivalence(packets: list[bytes], baseline: type) -> dict[str, float]:
    """Tick ``baseline`` and this tree's node on the same packets and compare every message
    they publish: how many are byte-identical, and the largest differences."""
    from lcmtypes import contact_t, robot_state_t
    from processes.state_estimator.process import StateEstimatorNode

    runs = []
    for name, cls in (("baseline", baseline), ("this tree", StateEstimatorNode)):
        d = NodeDriver(cls(), encoded=True)
        with progress(len(packets), f"equivalence: {name}", unit="tick") as bar:  # untimed
            for raw in packets:
                d.tick(robot_output=raw)
                bar.update(1)
        runs.append(d.sent)
    a, b = runs
    out = {"equiv_messages": float(sum(map(len, b.values()))), "equiv_roles_differ": float(
        {r: len(m) for r, m in a.items()} != {r: len(m) for r, m in b.items()})}
    same = states = mismatches = 0
    big: dict[str, float] = {"q": 0.0, "v": 0.0, "alip_x": 0.0, "alip_stance_pos": 0.0,
                             "contact_force": 0.0, "spring_deflection": 0.0}
    for x, y in zip(a["contact"], b["contact"], strict=False):
        mx, my = contact_t.decode(x), contact_t.decode(y)
        mismatches += mx.in_contact != my.in_contact
        big["contact_force"] = max(big["contact_force"], float(np.abs(
            np.subtract(mx.force_estimate, my.force_estimate)).max()))
        big["spring_deflection"] = max(big["spring_deflection"], float(np.abs(
            np.subtract(mx.spring_deflection, my.spring_deflection)).max()))
    for x, y in zip(a["state"] + a["network_state"], b["state"] + b["network_state"],
                    strict=False):
        mx, my = robot_state_t.decode(x), robot_state_t.decode(y)
        states += 1
        same += x == y
        for f in ("alip_stance", "in_contact", "status", "target_status", "packet_seq",
                  "packets_lost", "packets_rejected", "motor_torque", "imu_accel"):
            mismatches += getattr(mx, f) != getattr(my, f)
        for f in ("q", "v", "alip_x", "alip_stance_pos"):
            big[f] = max(big[f], float(np.abs(np.subtract(getattr(mx, f), getattr(my, f))).max()))
    out["equiv_states"] = float(states)
    out["equiv_states_byte_identical_ratio"] = same / max(states, 1)
    out["equiv_field_mismatches"] = float(mismatches)
    for k, v in big.items():
        out[f"equiv_{k}_max_abs_diff"] = v
    return out


def accuracy(rec: Any) -> dict[str, float]:
    """Error figures of a recorded run against the sim's ground truth."""
    from tools.testbed.estimator_motions import errors

    e = errors(rec)
    vel, pos = e["vel"], e["pos"]
    path = float(np.linalg.norm(np.diff(e["true_pos"], axis=0), axis=1).sum())
    final = float(np.linalg.norm(pos[-1]))
    agree = (e["est_contact"] == e["true_contact"]).mean()
    false_contact = (e["est_contact"] & ~e["true_contact"]).mean()
    return {
        "states": len(e["t"]),
        "vel_rmse_x_m_s": float(np.sqrt((vel[:, 0] ** 2).mean())),
        "vel_rmse_y_m_s": float(np.sqrt((vel[:, 1] ** 2).mean())),
        "vel_rmse_z_m_s": float(np.sqrt((vel[:, 2] ** 2).mean())),
        "vel_rmse_m_s": float(np.sqrt((vel**2).sum(axis=1).mean())),
        "vel_err_max_m_s": float(np.abs(vel).max()),
        "true_vel_rms_m_s": float(np.sqrt((e["true_vel"] ** 2).sum(axis=1).mean())),
        "pos_err_max_xy_m": float(np.abs(pos[:, :2]).max()),
        "pos_err_max_z_m": float(np.abs(pos[:, 2]).max()),
        "pos_drift_final_m": final,
        "pelvis_path_m": path,
        "pos_drift_per_m": final / path if path > 0 else float("nan"),
        "contact_agreement_ratio": float(agree),
        "false_contact_ratio": float(false_contact),
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="cassie bench estimator", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--json", default=None, help="write the figures as one flat JSON object")
    ap.add_argument("--seconds", type=float, default=4.0, help="sim seconds of the scripted run")
    ap.add_argument("--motion", default="steps", help="scripted motion: still, squat, steps")
    ap.add_argument("--baseline", metavar="REV", default=None,
                    help="also time the estimator of git revision REV on the same packets, "
                         "interleaved with this tree's (3 repeats each), and print the ratios")
    ap.add_argument("--live", action="store_true",
                    help="also run the estimator live (LiveRunner on CPU 1 at SCHED_FIFO, fed "
                         "over UDP at 2 kHz from CPU 0, two CASSIE_STATE subscribers), beside "
                         "the --baseline's in interleaved segments")
    ap.add_argument("--live-seconds", type=float, default=3.0,
                    help="wall seconds of each live segment (default 3)")
    ap.add_argument("--live-repeats", type=int, default=3,
                    help="live segments per estimator, interleaved (default 3)")
    args = ap.parse_args(argv)
    from tools.testbed.estimator_motions import MOTIONS, run_loop

    if args.motion not in MOTIONS:
        ap.error(f"--motion must be one of {', '.join(MOTIONS)}")
    baseline = baseline_node(args.baseline) if args.baseline else None  # fail before the run
    if args.live and (args.live_seconds <= LIVE_WARMUP_S + 0.3 or args.live_repeats < 1):
        ap.error(f"--live-seconds must exceed {LIVE_WARMUP_S + 0.3:g} and --live-repeats be "
                 "at least 1")
    t0 = time.perf_counter()
    with progress(args.seconds, f"scripted {args.motion} run", unit="sim s",
                  bar_format="{l_bar}{bar}| {n:.1f}/{total:g} sim s [{elapsed}<{remaining}]"
                  ) as bar:
        rec = run_loop(args.motion, args.seconds,
                       progress=lambda t_us: bar.update(t_us / 1e6 - bar.n))
    run_s = time.perf_counter() - t0
    acc = accuracy(rec)
    load_before = machine_load(200)
    node_ms, cpu_ms, upd_ms = time_ticks(rec.packets)
    load = machine_load(200)
    load = {k: max(load[k], load_before[k]) for k in load}
    figures: dict[str, Any] = {
        "description": f"scripted '{args.motion}' run of {args.seconds:g} s (real MuJoCo sim, "
                       "soft pelvis holder, joint PD) in the deterministic harness; "
                       "tick = decode + checks + estimate + 3 LCM encodes",
        "motion": args.motion,
        "sim_seconds": args.seconds,
    }
    figures.update(summarize(node_ms, "tick"))
    # p10: what a tick costs when the shared CPU is not contended (the median is not, there)
    figures["tick_p10_ms"] = float(np.percentile(node_ms, 10))
    figures["tick_over_period_ratio"] = float((node_ms > PERIOD_MS).mean())
    figures.update(summarize(cpu_ms, "tick_cpu"))
    figures.update(summarize(upd_ms, "update"))
    figures["update_p10_ms"] = float(np.percentile(upd_ms, 10))
    figures.update(acc)
    figures.update(load)
    figures["harness_run_s"] = run_s
    print_table("state estimator: tick time (ms)", {
        "ticks": len(node_ms),
        "tick p10 (uncontended)": figures["tick_p10_ms"],
        "tick median": float(np.median(node_ms)),
        "tick p99": float(np.percentile(node_ms, 99)),
        "tick max": float(node_ms.max()),
        "ticks over 0.5 ms": f"{figures['tick_over_period_ratio']:.2%}",
        "tick CPU time median": float(np.median(cpu_ms)),
        "tick CPU time p99": float(np.percentile(cpu_ms, 99)),
        "update-only p10": figures["update_p10_ms"],
        "update-only median": float(np.median(upd_ms)),
        "update-only p99": float(np.percentile(upd_ms, 99)),
        "load average (1 min)": load["load_avg_1min"],
        "tiny numpy op (us)": load["ref_numpy_op_us"],
    })
    print_table(f"state estimator: error vs ground truth ({args.motion}, {args.seconds:g} s)", {
        "velocity RMSE (m/s) x, y, z": (f"{acc['vel_rmse_x_m_s']:.4f}, "
                                        f"{acc['vel_rmse_y_m_s']:.4f}, "
                                        f"{acc['vel_rmse_z_m_s']:.4f}"),
        "velocity RMSE, norm (m/s)": acc["vel_rmse_m_s"],
        "true velocity rms (m/s)": acc["true_vel_rms_m_s"],
        "position error max xy / z (m)": (f"{acc['pos_err_max_xy_m']:.4f} / "
                                          f"{acc['pos_err_max_z_m']:.4f}"),
        "final drift (m)": acc["pos_drift_final_m"],
        "pelvis path (m)": acc["pelvis_path_m"],
        "drift per metre of path": acc["pos_drift_per_m"],
        "contact agreement": f"{acc['contact_agreement_ratio']:.1%}",
        "false contact": f"{acc['false_contact_ratio']:.2%}",
    })
    if baseline is not None:
        sbs = side_by_side(rec.packets, baseline)
        figures["baseline_rev"] = args.baseline
        figures.update(sbs)
        print_table(f"side by side: baseline {args.baseline} vs this tree (ms, "
                    f"{sbs['side_by_side_repeats']} interleaved repeats)", [
            (f"tick {k}", f"{sbs[f'baseline_tick_{k}_ms']:.4f} -> {sbs[f'this_tick_{k}_ms']:.4f}"
                          f"  ({sbs[f'speedup_{k}_ratio']:.2f}x)")
            for k in ("p10", "median", "p99")] + [
            ("tick max", f"{sbs['baseline_tick_max_ms']:.3f} -> {sbs['this_tick_max_ms']:.3f}"),
            ("ticks over 0.5 ms", f"{sbs['baseline_tick_over_period_ratio']:.2%} -> "
                                  f"{sbs['this_tick_over_period_ratio']:.2%}")])
    if baseline is not None:
        eq = equivalence(rec.packets, baseline)
        figures.update(eq)
        print_table(f"equivalence: every message of baseline {args.baseline} and this tree on "
                    "the same packets", [
            ("messages (state, network, contact)", f"{eq['equiv_messages']:.0f}"),
            ("states byte-identical", f"{eq['equiv_states_byte_identical_ratio']:.2%} of "
                                      f"{eq['equiv_states']:.0f}"),
            ("integer/flag field mismatches", f"{eq['equiv_field_mismatches']:.0f}"),
            *[(f"max |diff| {k}", f"{eq[f'equiv_{k}_max_abs_diff']:.3g}") for k in (
                "q", "v", "alip_x", "alip_stance_pos", "contact_force", "spring_deflection")]])
    if args.live:
        variants: dict[str, Path | None] = {"this": None}
        if args.baseline:
            variants = {"baseline": baseline_root(args.baseline), "this": None}
        load_before = machine_load(200)
        live = live_run(rec.packets, variants, args.live_seconds, args.live_repeats)
        load_after = machine_load(200)
        names = list(variants)
        figures.update(live_figures(live, names))
        figures["live_segment_s"] = args.live_seconds
        figures["live_repeats"] = args.live_repeats
        figures["live_load_avg_1min"] = max(load_before["load_avg_1min"],
                                            load_after["load_avg_1min"])
        print_live(live, names, f"live: LiveRunner on CPU 1 (SCHED_FIFO), UDP 2 kHz from CPU 0, "
                                f"2 subscribers; {args.live_repeats} x {args.live_seconds:g} s "
                                "per estimator, interleaved"
                                + (f"; baseline {args.baseline}" if args.baseline else ""))
        if "baseline" in variants and "live_cpu_share_reduction_ratio" in figures:
            print(f"  CPU share: {figures['live_cpu_share_reduction_ratio']:.1%} less than the "
                  f"baseline; tick CPU median {figures['live_tick_cpu_median_speedup_ratio']:.2f}x"
                  f", p99 {figures['live_tick_cpu_p99_speedup_ratio']:.2f}x")
        print(f"  load average (1 min) {figures['live_load_avg_1min']:.2f}")
    write_json(args.json, "estimator", figures)
    return 0


if __name__ == "__main__":
    import sys

    if sys.argv[1:2] == ["_live_child"]:
        raise SystemExit(_live_child(sys.argv[2:]))
    raise SystemExit(main())
