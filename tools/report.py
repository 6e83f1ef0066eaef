"""`cassie report LOG`: a timing report from an LCM log (lcm-logger, or `cassie launch --log`).

Per channel: message count, rate and gaps. Per loop (from the processes' own TIMING messages,
which carry every tick's raw samples): execution time, CPU time, lateness and input-age
percentiles and deadline misses. Per process: its share of a core (CPU seconds over wall
seconds, all its threads) and CPU seconds per second of sim time, beside its budget, and the
stack's total against the machine's (the supervisor's status adds the watchers: loggers,
dashboard, the supervisor itself). Real time: the sim's real-time factor, a state for every
sim packet, a torque for every sim step (from the nodes' counters). Per hop (a message and
the first message derived from it, matched by the ``header.utime`` of the robot state both
derive from): latency percentiles. Everything is checked against ``hw_config/budgets.yaml``.
"""

from __future__ import annotations

import argparse
import re
import sys
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import lcm
import numpy as np

import lcmtypes
from runtime.config import HW_CONFIG_DIR, _channel, load_yaml
from runtime.errors import ConfigError
from runtime.timing import FOREIGN_CLOCK_NS
from tools.benchmarks.common import print_columns, write_json

PCTS = (50.0, 99.0, 99.9)


def _types_by_fingerprint() -> dict[bytes, type]:
    out = {}
    for name in dir(lcmtypes):
        cls = getattr(lcmtypes, name)
        if isinstance(cls, type) and hasattr(cls, "_get_packed_fingerprint"):
            out[cls._get_packed_fingerprint()] = cls
    return out


LOOP_LIMITS = ("exec_median_ms", "exec_p99_ms", "exec_p999_ms", "exec_max_ms", "rate_min_hz",
               "miss_ratio_max")
REALTIME_LIMITS = ("rtf_min", "states_per_packet_min", "torques_per_step_min")


@dataclass
class Budgets:
    loops: dict[str, dict[str, float]] = field(default_factory=dict)
    hops: list[dict[str, Any]] = field(default_factory=list)
    cpu: dict[str, float] = field(default_factory=dict)  # process -> max share of a core
    cpu_total: float = 0.0  # max share of one core summed over every process
    realtime: dict[str, float] = field(default_factory=dict)


def load_budgets(path: Path) -> Budgets:
    """Read and check a budgets file; hop channel keys are resolved to channel names."""
    data = load_yaml(path)
    chans_file = (path.parent / str(data.get("channels_file", "channels.yaml"))).resolve()
    raw = load_yaml(chans_file).get("channels", {}) if chans_file.exists() else {}
    names = {k: _channel(k, v, chans_file).name for k, v in raw.items()}
    names.update({str(k): str(v) for k, v in (data.get("channels") or {}).items()})
    loops = {}
    for proc, limits in (data.get("loops") or {}).items():
        if not isinstance(limits, dict):
            raise ConfigError(str(path), f"loops.{proc}", "must be a mapping of limits")
        for k, v in limits.items():
            if k not in LOOP_LIMITS or not isinstance(v, (int, float)) or v <= 0:
                raise ConfigError(
                    str(path),
                    f"loops.{proc}.{k}",
                    f"bad limit {v!r}",
                    allowed=", ".join(LOOP_LIMITS) + ": a number > 0",
                )
        loops[str(proc)] = {k: float(v) for k, v in limits.items()}
    cpu: dict[str, float] = {}
    total = 0.0
    for proc, v in (data.get("cpu") or {}).items():
        if isinstance(v, bool) or not isinstance(v, (int, float)) or v <= 0:
            raise ConfigError(str(path), f"cpu.{proc}", f"bad CPU share {v!r}",
                              allowed="a share of one core > 0 (1.0 = a whole core)")
        if proc == "total":
            total = float(v)
        else:
            cpu[str(proc)] = float(v)
    rt = data.get("realtime") or {}
    for k, v in rt.items():
        if k not in REALTIME_LIMITS or isinstance(v, bool) or not isinstance(v, (int, float)):
            raise ConfigError(str(path), f"realtime.{k}", f"bad limit {v!r}",
                              allowed=", ".join(REALTIME_LIMITS) + ": a number")
    hops = []
    for i, hop in enumerate(data.get("hops") or []):
        for end in ("from", "to"):
            if hop.get(end) not in names:
                raise ConfigError(
                    str(path),
                    f"hops[{i}].{end}",
                    f"unknown channel {hop.get(end)!r}",
                    allowed=", ".join(sorted(names)),
                )
        hops.append(
            {
                "name": str(hop.get("name", f"{hop['from']} -> {hop['to']}")),
                "from": names[hop["from"]],
                "to": names[hop["to"]],
                "p99_ms": float(hop.get("p99_ms", 0.0)),
            }
        )
    return Budgets(loops, hops, cpu, total, {k: float(v) for k, v in rt.items()})


def analyse(log_path: Path, budgets: Budgets) -> dict[str, Any]:
    """Read the whole log once and compute every table of the report."""
    types = _types_by_fingerprint()
    arrivals: dict[str, list[int]] = defaultdict(list)
    undecodable: dict[str, int] = defaultdict(int)
    timing: dict[tuple[str, str], list[Any]] = defaultdict(list)
    timing_ts: dict[tuple[str, str], list[int]] = defaultdict(list)  # log receive time, us
    watchers: dict[str, list[tuple[int, float]]] = defaultdict(list)  # name -> (ts, cpu_s)
    hop_ends = {h["from"] for h in budgets.hops} | {h["to"] for h in budgets.hops}
    sent: dict[str, dict[int, int]] = defaultdict(dict)  # channel -> utime -> first send ns
    try:
        log = lcm.EventLog(str(log_path), "r")
    except OSError as exc:
        raise SystemExit(f"cannot read LCM log {log_path}: {exc}") from exc
    for event in log:
        if event.channel == "LCM_SELF_TEST":  # LCM's own start-up probe, not ours
            continue
        arrivals[event.channel].append(event.timestamp)
        cls = types.get(event.data[:8])
        if cls is None:
            undecodable[event.channel] += 1
            continue
        if cls not in (lcmtypes.loop_timing_t, lcmtypes.supervisor_status_t) and (
                event.channel not in hop_ends):
            continue  # counted, never decoded
        try:
            m = cls.decode(event.data)
        except Exception:
            undecodable[event.channel] += 1
            continue
        if cls is lcmtypes.loop_timing_t:
            timing[(m.process, m.loop)].append(m)
            timing_ts[(m.process, m.loop)].append(event.timestamp)
        elif cls is lcmtypes.supervisor_status_t:
            for ps in m.processes:
                if ps.cpu_s > 0:
                    watchers[ps.name].append((event.timestamp, ps.cpu_s))
        else:
            h = m.header
            sent[event.channel].setdefault(int(h.utime), int(h.send_mono_ns))
    channels = {}
    for ch, ts in sorted(arrivals.items()):
        t = np.asarray(ts, dtype=np.int64)
        span = (t[-1] - t[0]) / 1e6 if t.size > 1 else 0.0
        gaps = np.diff(t) / 1e3 if t.size > 1 else np.zeros(1)
        channels[ch] = {
            "count": int(t.size),
            "rate_hz": (t.size - 1) / span if span > 0 else 0.0,
            "gap_median_ms": float(np.median(gaps)),
            "gap_max_ms": float(gaps.max()),
            "undecodable": undecodable.get(ch, 0),
        }
    loops = {}
    #: the raw samples behind the tables (for ``--plots``; not in the JSON)
    samples: dict[str, dict[str, np.ndarray]] = {"loops": {}, "hops": {}}
    for (proc, loop), msgs in sorted(timing.items()):
        msgs = [m for m in msgs if m.kind != "main"]  # a non-Node process's start signal
        if not msgs:
            continue
        ex = np.concatenate([np.asarray(m.exec_ms, dtype=float) for m in msgs])
        la = np.concatenate([np.asarray(m.lateness_ms, dtype=float) for m in msgs])
        ag = np.concatenate([np.asarray(m.input_age_ms, dtype=float) for m in msgs])
        cp = np.concatenate([np.asarray(m.cpu_ms, dtype=float) for m in msgs])
        ag = ag[ag >= 0]
        ticks = int(sum(m.ticks for m in msgs))
        misses = int(sum(m.deadline_misses for m in msgs))
        row: dict[str, Any] = {
            "process": proc,
            "loop": loop,
            "kind": msgs[-1].kind,
            "ticks": ticks,
            "rate_hz": float(np.median([m.rate_hz for m in msgs if m.ticks] or [0.0])),
            "deadline_ms": msgs[-1].deadline_ms,
            "deadline_misses": misses,
            "miss_ratio": misses / ticks if ticks else 0.0,
            "overruns": int(msgs[-1].overruns_total),
            "stale_skipped": int(msgs[-1].stale_skipped_total),
            "decode_errors": int(msgs[-1].decode_errors_total),
        }
        row.update(_pcts(ex, "exec"))
        row.update(_pcts(cp, "cpu"))
        row.update(_pcts(la, "lateness"))
        row.update(_pcts(ag, "input_age"))
        limits = budgets.loops.get(proc, {})
        row["budget"] = ", ".join(
            f"{k}>={v:g}" if k.endswith("_min_hz") else f"{k}<={v:g}" for k, v in limits.items()
        )
        row["within_budget"] = all(_within(row, k, v) for k, v in limits.items())
        loops[f"{proc}/{loop}"] = row
        samples["loops"][f"{proc}/{loop}"] = ex
    cpu = _cpu_table(timing, timing_ts, watchers, budgets)
    realtime = _realtime(timing, timing_ts, budgets, cpu.get("window"))
    hops = {}
    for hop in budgets.hops:
        a, b = sent.get(hop["from"], {}), sent.get(hop["to"], {})
        diffs = np.array([b[u] - a[u] for u in b if u in a], dtype=np.int64)
        # a pair more than FOREIGN_CLOCK_NS apart is not two stamps of one clock moments
        # apart (a replayed log re-published beside the live output, or two hosts' clocks):
        # counted, not a latency (a replay once read as a 161,616 ms hop)
        ok = (diffs >= 0) & (diffs <= FOREIGN_CLOCK_NS)
        lat = diffs[ok] / 1e6
        row = {
            "from": hop["from"],
            "to": hop["to"],
            "matched": int(lat.size),
            "foreign_clock": int(np.count_nonzero(diffs > FOREIGN_CLOCK_NS)),
            "budget_p99_ms": hop["p99_ms"],
        }
        row.update(_pcts(lat, "latency"))
        row["within_budget"] = bool(lat.size) and (
            hop["p99_ms"] <= 0 or row["latency_p99_ms"] <= hop["p99_ms"]
        )
        hops[hop["name"]] = row
        samples["hops"][hop["name"]] = lat
    return {"channels": channels, "loops": loops, "hops": hops, "cpu": cpu, "realtime": realtime,
            "samples": samples}


def _within(row: dict[str, Any], key: str, limit: float) -> bool:
    """A loop limit: exec_*_ms against the percentiles, rate_min_hz, miss_ratio_max."""
    if key == "rate_min_hz":
        return row["rate_hz"] >= limit
    if key == "miss_ratio_max":
        return row["miss_ratio"] <= limit
    name = {"exec_median_ms": "exec_p50_ms"}.get(key, key)
    return row.get(name, 0.0) <= limit


#: the CPU table's window opens this long after the last process's first TIMING message:
#: first calls (numba kernels loaded or compiled, first solves, page faults) are start-up
CPU_SETTLE_S = 2.0


def _clip(msgs: list[Any], ts: list[int],
          window: tuple[int, int] | None) -> tuple[list[Any], list[int]]:
    """The samples inside ``window`` (all of them without one, or when fewer than two are)."""
    if window is None:
        return msgs, ts
    inside = [i for i, t in enumerate(ts) if window[0] <= t <= window[1]]
    if len(inside) < 2:
        return msgs, ts
    return [msgs[i] for i in inside], [ts[i] for i in inside]


def _span(ts: list[int], values: list[float],
          window: tuple[int, int] | None = None) -> tuple[float, float]:
    """(value difference, wall seconds) between the first and last sample (of those inside
    ``window``, log microseconds, when it holds two)."""
    values, ts = _clip(values, ts, window)
    if len(ts) < 2:
        return 0.0, 0.0
    return values[-1] - values[0], (ts[-1] - ts[0]) / 1e6


def _common_window(spans: list[tuple[int, int]]) -> tuple[int, int] | None:
    """The stretch of log time in which every process was up and settled: from the last
    first sample plus ``CPU_SETTLE_S`` to the first last one (None when shorter than 2 s), so
    the shares add up to what the machine carried at one time."""
    if not spans:
        return None
    lo = max(a for a, _ in spans) + int(CPU_SETTLE_S * 1e6)
    hi = min(b for _, b in spans)
    return (lo, hi) if hi - lo >= 2_000_000 else None


def _cpu_table(
    timing: dict[tuple[str, str], list[Any]],
    timing_ts: dict[tuple[str, str], list[int]],
    watchers: dict[str, list[tuple[int, float]]],
    budgets: Budgets,
) -> dict[str, Any]:
    """Per process: share of a core (its CPU seconds over wall seconds, all its threads) and
    CPU seconds per sim second; the watchers from the supervisor's status; the total. All over
    the one window in which every process ran (``_common_window``), start-up left out."""
    rows: dict[str, dict[str, Any]] = {}
    sim_rate = float("nan")  # sim seconds per wall second, to give watchers a per-sim figure
    series: dict[str, tuple[list[Any], list[int]]] = {}
    for (proc, _loop), msgs in timing.items():
        ts = timing_ts[(proc, _loop)]
        keep = [i for i, m in enumerate(msgs) if m.kind != "main"]
        if len(keep) >= 2 and proc not in series:
            series[proc] = ([msgs[i] for i in keep], [ts[i] for i in keep])
    window = _common_window([(tt[0], tt[-1]) for _, tt in series.values()])
    for proc, (ms, tt) in series.items():
        ms, tt = _clip(ms, tt, window)
        dcpu, dwall = _span(tt, [m.process_cpu_s for m in ms])
        dsim = (ms[-1].header.utime - ms[0].header.utime) / 1e6
        if proc == "sim" and dwall > 0:
            sim_rate = dsim / dwall
        rows[proc] = {
            "source": "TIMING",
            "cpu_s": dcpu,
            "wall_s": dwall,
            "cpu_share": dcpu / dwall if dwall > 0 else 0.0,
            "cpu_per_sim_s": dcpu / dsim if dsim > 0 else float("nan"),
        }
    for name, samples in watchers.items():
        if len(samples) < 2:
            continue
        # the supervisor's samples cover the whole process tree (a depth renderer too): they
        # win where both exist
        dcpu, dwall = _span([t for t, _ in samples], [c for _, c in samples], window)
        share = dcpu / dwall if dwall > 0 else 0.0
        per_sim = rows[name]["cpu_per_sim_s"] * share / rows[name]["cpu_share"] if (
            name in rows and rows[name]["cpu_share"] > 0) else share / sim_rate
        rows[name] = {"source": "supervisor", "cpu_s": dcpu, "wall_s": dwall,
                      "cpu_share": share, "cpu_per_sim_s": per_sim}
    for name, row in rows.items():
        limit = budgets.cpu.get(name)
        row["budget_share"] = limit if limit is not None else float("nan")
        row["within_budget"] = limit is None or row["cpu_share"] <= limit
    total = sum(r["cpu_share"] for r in rows.values())
    return {
        "processes": dict(sorted(rows.items())),
        "total_share": total,
        "window": window,
        "window_s": (window[1] - window[0]) / 1e6 if window is not None else float("nan"),
        "total_budget": budgets.cpu_total,
        "within_budget": budgets.cpu_total <= 0 or total <= budgets.cpu_total,
    }


def _counter_series(msgs: list[Any], ts: list[int], name: str) -> tuple[list[int], list[float]]:
    out_t, out_v = [], []
    for m, t in zip(msgs, ts, strict=True):
        if name in m.counter_names:
            out_t.append(t)
            out_v.append(m.counter_values[m.counter_names.index(name)])
    return out_t, out_v


def _delta_between(t: list[int], v: list[float], t0: int, t1: int) -> float:
    """Increase of a cumulative counter between wall times t0 and t1 (nearest samples)."""
    if not t:
        return 0.0
    a = np.searchsorted(t, t0)
    b = np.searchsorted(t, t1, side="right") - 1
    a, b = min(max(a, 0), len(t) - 1), min(max(b, 0), len(t) - 1)
    return v[b] - v[a] if b > a else 0.0


def _realtime(
    timing: dict[tuple[str, str], list[Any]],
    timing_ts: dict[tuple[str, str], list[int]],
    budgets: Budgets,
    window: tuple[int, int] | None = None,
) -> dict[str, Any]:
    """The sim's real-time factor, states per sim packet, torques per sim step: from the
    sim's and the estimator's counters, over the span both were running (inside ``window``,
    the CPU table's, when given)."""
    by_proc = {p: _clip(msgs, timing_ts[(p, lp)], window) for (p, lp), msgs in timing.items()}
    out: dict[str, Any] = {}
    sim = by_proc.get("sim")
    if sim is None:
        return out
    st, sv = _counter_series(*sim, "sim_time_s")
    if len(st) >= 2:
        out["rtf"] = (sv[-1] - sv[0]) / ((st[-1] - st[0]) / 1e6)
    _, steps = _counter_series(*sim, "steps")
    tt, sent = _counter_series(*sim, "packets_sent")
    _, cmds = _counter_series(*sim, "commands_received")
    if len(tt) >= 2 and steps and cmds:
        # from the first torque received (the stack takes seconds to come up behind the sim)
        first = next((i for i, c in enumerate(cmds) if c > 0), None)
        if first is not None and first < len(tt) - 1:
            ds = steps[-1] - steps[first]
            out["torques_per_step"] = (cmds[-1] - cmds[first]) / ds if ds > 0 else 0.0
    est = by_proc.get("state_estimator")
    if est is not None and len(tt) >= 2:
        et, pub = _counter_series(*est, "states_published")
        if len(et) >= 2:
            d_sent = _delta_between(tt, sent, et[0], et[-1])
            out["states_per_packet"] = (pub[-1] - pub[0]) / d_sent if d_sent > 0 else 0.0
    out["link"] = _link(by_proc)
    checks = {"rtf": "rtf_min", "states_per_packet": "states_per_packet_min",
              "torques_per_step": "torques_per_step_min"}
    out["budget"] = {k: budgets.realtime[v] for k, v in checks.items() if v in budgets.realtime}
    out["within_budget"] = all(out.get(k, 0.0) >= lim for k, lim in out["budget"].items())
    return out


#: the UDP link's two directions: (name, sender, its sent counter, receiver, its received
#: counter, the receiver's count of gaps in the sender's sequence numbers)
LINKS = (
    ("target PC -> estimator", "sim", "packets_sent", "state_estimator", "packets_received",
     "packets_lost", ("packets_rejected",)),
    ("torque bridge -> target PC", "torque_bridge", "packets_sent", "sim", "commands_received",
     "commands_lost", ("commands_malformed", "commands_foreign")),
)


def _rise(t: list[int], v: list[float], span: tuple[float, float]) -> float:
    """How much a counter sampled at times ``t`` rose over ``span`` (interpolated; 0 with
    fewer than two samples)."""
    if len(t) < 2:
        return 0.0
    return float(np.interp(span[1], t, v) - np.interp(span[0], t, v))


def _link(by_proc: dict[str, tuple[list[Any], list[int]]]) -> dict[str, dict[str, float]]:
    """Datagrams each way over the span both ends reported: sent by one end, received by the
    other, the difference (lost on the wire or in a full socket buffer: what an 8-bit seq
    cannot tell after a resend) and the receiver's own count of sequence gaps. Counters are
    interpolated at the span's ends, so the two processes' reports need not coincide."""
    out: dict[str, dict[str, float]] = {}
    for name, tx, sent_key, rx, recv_key, gap_key, rejected_keys in LINKS:
        if tx not in by_proc or rx not in by_proc:
            continue
        st, sv = _counter_series(*by_proc[tx], sent_key)
        rt_, rv = _counter_series(*by_proc[rx], recv_key)
        gt, gv = _counter_series(*by_proc[rx], gap_key)
        if len(st) < 2 or len(rt_) < 2:
            continue
        t0, t1 = max(st[0], rt_[0]), min(st[-1], rt_[-1])
        if t1 <= t0:
            continue
        span = (t0, t1)
        sent, recv, gaps = _rise(st, sv, span), _rise(rt_, rv, span), _rise(gt, gv, span)
        # arrived but refused: malformed, off range, another launch's token
        rejected = sum(_rise(*_counter_series(*by_proc[rx], key), span) for key in rejected_keys)
        out[name] = {"sent": sent, "received": recv, "lost": max(sent - recv, 0.0),
                     "lost_ratio": max(sent - recv, 0.0) / sent if sent > 0 else 0.0,
                     "seq_gaps": gaps, "rejected": rejected, "span_s": (t1 - t0) / 1e6}
    return out


def print_cpu(cpu: dict[str, Any], out: Any = None) -> None:
    """The CPU table: each process's share of a core beside its budget, and the total."""
    if not cpu or not cpu.get("processes"):
        return
    out = sys.stdout if out is None else out
    win = cpu.get("window_s", float("nan"))
    when = f"; the {win:.1f} s all ran, start-up left out" if win == win else ""
    out.write(f"\nCPU (share of one core = CPU seconds / wall seconds, all threads; per sim "
              f"second{when})\n---\n")
    rows = []
    for name, r in cpu["processes"].items():
        b = r["budget_share"]
        verdict = "" if b != b else ("ok" if r["within_budget"] else "OVER")
        per_sim = "" if r["cpu_per_sim_s"] != r["cpu_per_sim_s"] else f"{r['cpu_per_sim_s']:.3f}"
        rows.append([name, f"{r['cpu_s']:.2f}", f"{r['wall_s']:.1f}", f"{r['cpu_share']:.3f}",
                     per_sim, f"{'' if b != b else f'<={b:g}'} {verdict}".strip()])
    tb = cpu["total_budget"]
    verdict = "" if tb <= 0 else ("ok" if cpu["within_budget"] else
                                  f"OVER by {cpu['total_share'] - tb:.3f} core")
    rows.append(["total", "", "", f"{cpu['total_share']:.3f}", "",
                 f"{f'<={tb:g}' if tb > 0 else ''} {verdict}".strip()])
    print_columns(["process", "cpu s", "wall s", "share", "/sim s", "budget"], rows, out,
                  justify="lrrrrl")


def print_realtime(rt: dict[str, Any], out: Any = None) -> None:
    """Whether the sim kept wall-clock time and the chain answered every packet."""
    if not rt or not any(k in rt for k in ("rtf", "states_per_packet", "torques_per_step",
                                            "link")):
        return
    out = sys.stdout if out is None else out
    out.write("\nReal time (from the sim's and the estimator's counters, in the CPU table's "
              "window)\n---------\n")
    names = {"rtf": "sim real-time factor", "states_per_packet": "states per sim packet",
             "torques_per_step": "torques per sim step"}
    rows = []
    for key, label in names.items():
        if key not in rt:
            continue
        lim = rt["budget"].get(key)
        verdict = "" if lim is None else ("ok" if rt[key] >= lim else "UNDER")
        rows.append([label, f"{rt[key]:.4f}",
                     f"{'' if lim is None else f'>={lim:g}'} {verdict}".strip()])
    if rows:
        print_columns(["check", "ratio", "budget"], rows, out, justify="lrl")
    links = rt.get("link") or {}
    if links:
        out.write("\nUDP link (datagrams over the span both ends reported; lost = sent - "
                  "received)\n--------\n")
        print_columns(
            ["direction", "sent", "received", "lost", "lost %", "seq gaps", "rejected"],
            [[name, f"{r['sent']:.0f}", f"{r['received']:.0f}", f"{r['lost']:.0f}",
              f"{100 * r['lost_ratio']:.2f}", f"{r['seq_gaps']:.0f}",
              f"{r.get('rejected', 0.0):.0f}"] for name, r in links.items()], out)


def _pcts(a: np.ndarray, prefix: str) -> dict[str, float]:
    if a.size == 0:
        return {f"{prefix}_{k}_ms": float("nan") for k in ("p50", "p99", "p999", "max")}
    p50, p99, p999 = np.percentile(a, PCTS)
    return {
        f"{prefix}_p50_ms": float(p50),
        f"{prefix}_p99_ms": float(p99),
        f"{prefix}_p999_ms": float(p999),
        f"{prefix}_max_ms": float(a.max()),
    }


def print_loops(loops: dict[str, Any], out: Any = None) -> None:
    """The loops table of the report: execution time, lateness and deadline misses."""
    out = sys.stdout if out is None else out
    out.write("\nLoops (execution time; lateness; misses against the loop's deadline)\n-----\n")
    rows = []
    for name, r in loops.items():
        verdict = ("ok" if r["within_budget"] else "OVER") if r["budget"] else ""
        rows.append([name, f"{r['rate_hz']:.1f}", f"{r['exec_p50_ms']:.3f}",
                     f"{r['exec_p99_ms']:.3f}", f"{r['exec_p999_ms']:.3f}",
                     f"{r['exec_max_ms']:.2f}", f"{r['cpu_p50_ms']:.3f}",
                     f"{r['lateness_p99_ms']:.3f}", str(r["deadline_misses"]),
                     f"{100 * r['miss_ratio']:.3f}", f"{r['budget']} {verdict}".strip()])
    print_columns(["loop", "Hz", "p50", "p99", "p99.9", "max", "cpu p50", "late p99", "misses",
                   "miss %", "budget"], rows, out, justify="l" + "r" * 9 + "l")


def print_report(rep: dict[str, Any], out: Any = None) -> None:
    """Every table of the report: channels, loops, CPU, real time and hops."""
    out = sys.stdout if out is None else out
    out.write("\nChannels\n--------\n")
    print_columns(
        ["channel", "count", "rate Hz", "gap med ms", "gap max ms", "bad"],
        [[ch, str(r["count"]), f"{r['rate_hz']:.1f}", f"{r['gap_median_ms']:.3f}",
          f"{r['gap_max_ms']:.2f}", str(r["undecodable"])] for ch, r in rep["channels"].items()],
        out)
    print_loops(rep["loops"], out)
    print_cpu(rep.get("cpu", {}), out)
    print_realtime(rep.get("realtime", {}), out)
    out.write("\nHops (latency, ms, matched by header.utime)\n----\n")
    rows, notes = [], []
    for name, r in rep["hops"].items():
        verdict = "ok" if r["within_budget"] else ("no data" if not r["matched"] else "OVER")
        rows.append([name, str(r["matched"]), f"{r['latency_p50_ms']:.3f}",
                     f"{r['latency_p99_ms']:.3f}", f"{r['latency_p999_ms']:.3f}",
                     f"{r['latency_max_ms']:.2f}", f"{r['budget_p99_ms']:g} {verdict}"])
        if r.get("foreign_clock"):
            notes.append(f"  {name}: {r['foreign_clock']} pairs over 1 s apart left out (a "
                         "replayed log, or two hosts' clocks)\n")
    print_columns(["hop", "n", "p50", "p99", "p99.9", "max", "budget p99"], rows, out,
                  justify="lrrrrrl")
    out.write("".join(notes))


def flatten(rep: dict[str, Any]) -> dict[str, Any]:
    """The report as one flat object of figures whose names carry their unit."""
    flat: dict[str, Any] = {}
    for ch, r in rep["channels"].items():
        flat[f"channel_{ch}_rate_hz"] = r["rate_hz"]
        flat[f"channel_{ch}_gap_max_ms"] = r["gap_max_ms"]
    for name, r in rep["loops"].items():
        key = name.replace("/", "_")
        for k, v in r.items():
            if k.endswith(("_ms", "_hz", "_ratio")) or k in ("deadline_misses", "ticks"):
                flat[f"loop_{key}_{k}"] = v
    for name, r in rep["hops"].items():
        key = re.sub(r"[^0-9A-Za-z]+", "_", name).strip("_")
        for k, v in r.items():
            if k.endswith("_ms") or k == "matched":
                flat[f"hop_{key}_{k}"] = v
    cpu = rep.get("cpu") or {}
    for name, r in (cpu.get("processes") or {}).items():
        flat[f"cpu_{name}_share"] = r["cpu_share"]
        flat[f"cpu_{name}_per_sim_s"] = r["cpu_per_sim_s"]
    if cpu:
        flat["cpu_total_share"] = cpu["total_share"]
    for k in ("rtf", "states_per_packet", "torques_per_step"):
        if k in (rep.get("realtime") or {}):
            flat[f"realtime_{k}_ratio"] = rep["realtime"][k]
    for name, r in ((rep.get("realtime") or {}).get("link") or {}).items():
        key = re.sub(r"[^0-9A-Za-z]+", "_", name).strip("_")
        flat[f"link_{key}_sent_count"] = r["sent"]
        flat[f"link_{key}_lost_count"] = r["lost"]
        flat[f"link_{key}_lost_ratio"] = r["lost_ratio"]
        flat[f"link_{key}_seq_gaps_count"] = r["seq_gaps"]
        flat[f"link_{key}_rejected_count"] = r.get("rejected", 0.0)
    return flat


def plot(rep: dict[str, Any], log_path: Path, out_dir: Path) -> list[Path]:
    """PNG histograms of execution time per loop and latency per hop, one panel each, with
    the medians, p99s, deadlines and budgets drawn (needs matplotlib)."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        from matplotlib import ticker
    except ImportError as exc:
        raise SystemExit("--plots needs matplotlib: pip install matplotlib") from exc
    out_dir.mkdir(parents=True, exist_ok=True)
    samples = rep.get("samples") or {"loops": {}, "hops": {}}
    paths = []

    def panels(kind: str, title: str, xlabel: str, marks: Any) -> Path | None:
        data = {n: a for n, a in samples[kind].items() if a.size}
        if not data:
            return None
        cols = 2 if len(data) > 1 else 1
        rows = (len(data) + cols - 1) // cols
        fig, axes = plt.subplots(rows, cols, figsize=(6.5 * cols, 2.6 * rows), squeeze=False)
        for ax, (name, a) in zip(axes.flat, data.items(), strict=False):
            lo = max(float(a.min()), 1e-3)
            hi = max(float(a.max()), lo * 1.01)
            bins = np.geomspace(lo, hi, 60)  # log bins: the tail is what matters
            ax.hist(a, bins=bins, color="#4c72b0")
            ax.set_xscale("log")
            ax.set_yscale("log")
            ax.xaxis.set_major_formatter(ticker.FormatStrFormatter("%g"))
            # within about a decade the major ticks alone leave the axis nearly bare
            ax.xaxis.set_minor_formatter(ticker.FormatStrFormatter("%g") if hi / lo < 30
                                         else ticker.NullFormatter())
            ax.tick_params(axis="x", which="minor", labelsize=7)
            p50, p99 = np.percentile(a, [50, 99])
            ax.axvline(p50, color="k", lw=1, label=f"median {p50:.3f} ms")
            ax.axvline(p99, color="k", lw=1, ls="--", label=f"p99 {p99:.3f} ms")
            for value, label, color in marks(name):
                ax.axvline(value, color=color, lw=1.5, label=label)
            ax.set_title(f"{name} (n={a.size:,})", fontsize=10)
            ax.set_xlabel(xlabel)
            ax.set_ylabel("count")
            ax.legend(fontsize=7, loc="upper right")
        for ax in list(axes.flat)[len(data):]:
            ax.axis("off")
        fig.suptitle(f"{title}: {log_path.name}", fontsize=11)
        fig.tight_layout()
        p = out_dir / f"{kind}_{'exec' if kind == 'loops' else 'latency'}_hist.png"
        fig.savefig(p, dpi=90)
        plt.close(fig)
        return p

    def loop_marks(name: str) -> list[tuple[float, str, str]]:
        r = rep["loops"][name]
        out = []
        if r.get("deadline_ms"):
            out.append((float(r["deadline_ms"]), f"deadline {r['deadline_ms']:g} ms", "red"))
        for part in str(r.get("budget", "")).split(", "):
            m = re.match(r"exec_(p\d+|median)_ms<=([0-9.]+)", part)
            if m:
                out.append((float(m.group(2)), f"budget {m.group(1)} <= {m.group(2)} ms",
                            "orange"))
        return out

    def hop_marks(name: str) -> list[tuple[float, str, str]]:
        b = rep["hops"][name].get("budget_p99_ms") or 0.0
        return [(float(b), f"budget p99 <= {b:g} ms", "orange")] if b > 0 else []

    for kind, title, xlabel, marks in (
            ("loops", "Execution time per loop", "execution time, ms", loop_marks),
            ("hops", "Latency per hop", "latency, ms", hop_marks)):
        if (p := panels(kind, title, xlabel, marks)) is not None:
            paths.append(p)
    return paths


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="cassie report",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    ap.add_argument("log", type=Path, help="an LCM log file (lcm-logger)")
    ap.add_argument("--json", type=Path, default=None, help="write the figures as flat JSON")
    ap.add_argument("--plots", type=Path, default=None, help="write PNG plots into this folder")
    ap.add_argument("--budgets", type=Path, default=HW_CONFIG_DIR / "budgets.yaml")
    args = ap.parse_args(argv)
    if not args.log.exists():
        print(f"no such log file: {args.log}", file=sys.stderr)
        return 2
    rep = analyse(args.log, load_budgets(args.budgets))
    print(f"timing report of {args.log}")
    print_report(rep)
    if args.json:
        write_json(
            args.json,
            "report",
            {"description": f"timing report of {args.log.name}", **flatten(rep)},
        )
    if args.plots:
        for p in plot(rep, args.log, args.plots):
            print(f"wrote {p}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
