"""`cassie report LOG`: a timing report from an LCM log (lcm-logger, or `cassie launch --log`).

Per channel: message count, rate and gaps. Per loop (from the processes' own TIMING messages,
which carry every tick's raw samples): execution time, lateness and input-age percentiles and
deadline misses. Per hop (a message and the first message derived from it, matched by the
``header.utime`` of the robot state both derive from): latency percentiles. Everything is
checked against the budgets in ``hw_config/budgets.yaml``.
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
from tools.benchmarks.common import write_json

PCTS = (50.0, 99.0, 99.9)


def _types_by_fingerprint() -> dict[bytes, type]:
    out = {}
    for name in dir(lcmtypes):
        cls = getattr(lcmtypes, name)
        if isinstance(cls, type) and hasattr(cls, "_get_packed_fingerprint"):
            out[cls._get_packed_fingerprint()] = cls
    return out


@dataclass
class Budgets:
    loops: dict[str, dict[str, float]] = field(default_factory=dict)
    hops: list[dict[str, Any]] = field(default_factory=list)


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
            if k not in ("exec_median_ms", "exec_p99_ms", "exec_p999_ms", "exec_max_ms") or (
                not isinstance(v, (int, float)) or v <= 0
            ):
                raise ConfigError(
                    str(path),
                    f"loops.{proc}.{k}",
                    f"bad limit {v!r}",
                    allowed="exec_median_ms, exec_p99_ms, exec_p999_ms, exec_max_ms: a number > 0",
                )
        loops[str(proc)] = {k: float(v) for k, v in limits.items()}
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
    return Budgets(loops, hops)


def analyse(log_path: Path, budgets: Budgets) -> dict[str, Any]:
    """Read the whole log once and compute every table of the report."""
    types = _types_by_fingerprint()
    arrivals: dict[str, list[int]] = defaultdict(list)
    undecodable: dict[str, int] = defaultdict(int)
    timing: dict[tuple[str, str], list[Any]] = defaultdict(list)
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
        if cls is lcmtypes.loop_timing_t:
            try:
                m = cls.decode(event.data)
            except Exception:
                undecodable[event.channel] += 1
                continue
            timing[(m.process, m.loop)].append(m)
        elif event.channel in hop_ends:
            try:
                h = cls.decode(event.data).header
            except Exception:
                undecodable[event.channel] += 1
                continue
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
    for (proc, loop), msgs in sorted(timing.items()):
        ex = np.concatenate([np.asarray(m.exec_ms, dtype=float) for m in msgs])
        la = np.concatenate([np.asarray(m.lateness_ms, dtype=float) for m in msgs])
        ag = np.concatenate([np.asarray(m.input_age_ms, dtype=float) for m in msgs])
        ag = ag[ag >= 0]
        ticks = int(sum(m.ticks for m in msgs))
        misses = int(sum(m.deadline_misses for m in msgs))
        row: dict[str, Any] = {
            "process": proc,
            "loop": loop,
            "kind": msgs[-1].kind,
            "ticks": ticks,
            "rate_hz": float(np.median([m.rate_hz for m in msgs])),
            "deadline_ms": msgs[-1].deadline_ms,
            "deadline_misses": misses,
            "miss_ratio": misses / ticks if ticks else 0.0,
            "overruns": int(msgs[-1].overruns_total),
            "stale_skipped": int(msgs[-1].stale_skipped_total),
            "decode_errors": int(msgs[-1].decode_errors_total),
        }
        row.update(_pcts(ex, "exec"))
        row.update(_pcts(la, "lateness"))
        row.update(_pcts(ag, "input_age"))
        limits = budgets.loops.get(proc, {})
        row["budget"] = ", ".join(f"{k}<={v:g}" for k, v in limits.items())
        row["within_budget"] = all(row.get(k, 0.0) <= v for k, v in limits.items())
        loops[f"{proc}/{loop}"] = row
    hops = {}
    for hop in budgets.hops:
        a, b = sent.get(hop["from"], {}), sent.get(hop["to"], {})
        lat = np.array([(b[u] - a[u]) / 1e6 for u in b if u in a and b[u] >= a[u]])
        row = {
            "from": hop["from"],
            "to": hop["to"],
            "matched": int(lat.size),
            "budget_p99_ms": hop["p99_ms"],
        }
        row.update(_pcts(lat, "latency"))
        row["within_budget"] = bool(lat.size) and (
            hop["p99_ms"] <= 0 or row["latency_p99_ms"] <= hop["p99_ms"]
        )
        hops[hop["name"]] = row
    return {"channels": channels, "loops": loops, "hops": hops}


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


def print_loops(loops: dict[str, Any], out: Any = sys.stdout) -> None:
    """The loops table of the report: execution time, lateness and deadline misses."""
    w = out.write
    w("\nLoops (execution time; lateness; misses against the loop's deadline)\n-----\n")
    w(
        f"{'loop':<28}{'Hz':>8}{'p50':>8}{'p99':>8}{'p99.9':>8}{'max':>8}{'late p99':>9}"
        f"{'misses':>9}{'miss %':>8}  budget\n"
    )
    for name, r in loops.items():
        verdict = ("ok" if r["within_budget"] else "OVER") if r["budget"] else ""
        w(
            f"{name:<28}{r['rate_hz']:>8.1f}{r['exec_p50_ms']:>8.3f}{r['exec_p99_ms']:>8.3f}"
            f"{r['exec_p999_ms']:>8.3f}{r['exec_max_ms']:>8.2f}{r['lateness_p99_ms']:>9.3f}"
            f"{r['deadline_misses']:>9}{100 * r['miss_ratio']:>8.3f}  {r['budget']} {verdict}\n"
        )


def print_report(rep: dict[str, Any], out: Any = sys.stdout) -> None:
    w = out.write
    w("\nChannels\n--------\n")
    w(f"{'channel':<24}{'count':>9}{'rate Hz':>10}{'gap med ms':>12}{'gap max ms':>12}{'bad':>6}\n")
    for ch, r in rep["channels"].items():
        w(
            f"{ch:<24}{r['count']:>9}{r['rate_hz']:>10.1f}{r['gap_median_ms']:>12.3f}"
            f"{r['gap_max_ms']:>12.2f}{r['undecodable']:>6}\n"
        )
    print_loops(rep["loops"], out)
    w("\nHops (latency, ms, matched by header.utime)\n----\n")
    w(f"{'hop':<34}{'n':>7}{'p50':>8}{'p99':>8}{'p99.9':>8}{'max':>8}  budget p99\n")
    for name, r in rep["hops"].items():
        verdict = "ok" if r["within_budget"] else ("no data" if not r["matched"] else "OVER")
        w(
            f"{name:<34}{r['matched']:>7}{r['latency_p50_ms']:>8.3f}{r['latency_p99_ms']:>8.3f}"
            f"{r['latency_p999_ms']:>8.3f}{r['latency_max_ms']:>8.2f}  {r['budget_p99_ms']:g} "
            f"{verdict}\n"
        )


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
    return flat


def plot(rep: dict[str, Any], log_path: Path, out_dir: Path) -> list[Path]:
    """PNG histograms of execution time per loop and latency per hop (needs matplotlib)."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError as exc:
        raise SystemExit("--plots needs matplotlib: pip install matplotlib") from exc
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = []
    names = list(rep["loops"])
    if names:
        fig, ax = plt.subplots(figsize=(9, 1.2 + 0.5 * len(names)))
        ax.barh(names, [rep["loops"][n]["exec_p99_ms"] for n in names], label="p99")
        ax.barh(names, [rep["loops"][n]["exec_p50_ms"] for n in names], label="median")
        ax.set_xlabel("execution time, ms")
        ax.legend()
        fig.tight_layout()
        p = out_dir / "loops_exec.png"
        fig.savefig(p, dpi=100)
        plt.close(fig)
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
