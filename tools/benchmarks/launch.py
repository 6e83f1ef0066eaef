"""`cassie bench launch`: the whole stack's CPU per process in a real-time launch, this tree
beside a git baseline.

Each run is `cassie launch PROFILE --duration S --log` of one source tree (this one, and with
``--baseline REV`` that revision's, extracted with `git archive`), run one after the other
(two stacks cannot share the machine) in the same invocation, alternating with ``--repeats``.
Every process of the launch (the supervisor, its children and their children) is sampled
with psutil every half second, so the figures do not depend on what a revision's processes
report about themselves: each process's share of a core (CPU seconds over the seconds it was
alive), the total, and the ratio to the baseline. Each tree's own `cassie report` then runs
on its own log (the log formats differ between revisions), and its loops table and the
launch's result line are kept beside the CPU table.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import psutil

from tools.benchmarks.common import (
    REPO,
    extract_tree,
    print_columns,
    print_table,
    progress,
    say,
    write_json,
)

#: the supervisor's `cassie check` before anything starts (every node built once, ~3 s): a
#: start-up cost, not a share of the running stack's cores, so it is left out of the total
PRECHECK = "precheck (start-up)"


def _name(p: psutil.Process) -> str | None:
    """Which part of the stack a process is, from its command line; None while it has none
    to read (a child whose exec the kernel is still finishing, or a zombie)."""
    c = p.cmdline()
    if not c:
        return None
    for entry in ("run", "runtime.run"):  # `cassie run NAME`, `python -m runtime.run NAME`
        if entry in c and c.index(entry) + 1 < len(c):
            return c[c.index(entry) + 1]
    if any("lcm-logger" in x for x in c):
        return "lcm_logger"
    if "log" in c and "tools.cli" in c:
        return "logger"
    if "dashboard" in c:
        return "dashboard"
    if "launch" in c:
        return "supervisor"
    if "check" in c and "tools.cli" in c:
        return PRECHECK
    return p.name()


def run_launch(tree: Path, profile: str, duration_s: float, log_dir: Path,
               extra: list[str], on_sample: Callable[[], None] | None = None
               ) -> dict[str, Any]:
    """One launch of ``tree``; CPU seconds and lifetime per process name, and its output.
    ``on_sample`` is called after each sample of the processes (twice a second)."""
    env = dict(os.environ)
    env["PYTHONPATH"] = str(tree)
    cmd = [sys.executable, "-m", "tools.cli", "launch", profile, "--duration", str(duration_s),
           "--no-live", "--log", "--log-dir", str(log_dir), *extra]
    p = subprocess.Popen(cmd, cwd=tree, env=env, stdout=subprocess.PIPE,
                         stderr=subprocess.STDOUT, text=True)
    sup = psutil.Process(p.pid)
    seen: dict[int, dict[str, Any]] = {}
    t0 = time.monotonic()
    while p.poll() is None:
        try:
            procs = [sup, *sup.children(recursive=True)]
        except psutil.Error:
            break
        for pr in procs:
            try:
                t = pr.cpu_times()
                rec = seen.setdefault(pr.pid, {"first": time.monotonic()})
                # named again at every sample: a child caught between fork and exec reads as
                # its parent (or as nothing); the name it ends with is the one it runs as
                rec["name"] = _name(pr) or rec.get("name") or pr.name()
                rec["cpu_s"] = t.user + t.system
                rec["last"] = time.monotonic()
            except psutil.Error:
                pass
        if on_sample is not None:
            on_sample()
        time.sleep(0.5)
    out = p.stdout.read() if p.stdout else ""
    per: dict[str, dict[str, float]] = {}
    for rec in seen.values():
        d = per.setdefault(rec["name"], {"cpu_s": 0.0, "alive_s": 0.0})
        d["cpu_s"] += rec.get("cpu_s", 0.0)
        d["alive_s"] = max(d["alive_s"], rec.get("last", rec["first"]) - rec["first"])
    result = next((ln for ln in out.splitlines() if ln.startswith("result:")), "result: ?")
    # the summary's line (the last one), not an early status table's
    robot = next((ln for ln in reversed(out.splitlines()) if ln.startswith("robot:")), "")
    report = subprocess.run([sys.executable, "-m", "tools.cli", "report",
                             str(log_dir / "lcm.log")], cwd=tree, env=env, text=True,
                            capture_output=True).stdout
    return {"per": per, "result": result, "robot": robot, "report": report,
            "wall_s": time.monotonic() - t0}


def share(per: dict[str, dict[str, float]]) -> dict[str, float]:
    return {k: v["cpu_s"] / v["alive_s"] for k, v in per.items() if v["alive_s"] > 1.0}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="cassie bench launch", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--profile", default="hw_config/sim.yaml",
                    help="launch profile, relative to each tree (default hw_config/sim.yaml)")
    ap.add_argument("--duration", type=float, default=30.0, help="seconds per launch")
    ap.add_argument("--baseline", metavar="REV", default=None,
                    help="also launch git revision REV, one after the other, and compare")
    ap.add_argument("--repeats", type=int, default=1, help="launches per tree (alternating)")
    ap.add_argument("--keep", type=Path, default=None,
                    help="keep each launch's logs and report in this folder")
    ap.add_argument("--json", default=None, help="write the figures as flat JSON")
    ap.add_argument("--plot", type=Path, default=None,
                    help="write a PNG bar chart of each process's CPU share, tree beside tree")
    ap.add_argument("launch_args", nargs="*", help="extra `cassie launch` arguments "
                    "(after --), e.g. -- --dashboard")
    args = ap.parse_args(argv)
    trees = {"this": REPO}
    if args.baseline:
        trees = {"baseline": extract_tree(args.baseline), "this": REPO}
    work = args.keep or Path(tempfile.mkdtemp(prefix="bench-launch-"))
    runs: dict[str, list[dict[str, Any]]] = {k: [] for k in trees}
    # one step per launch (each its start-up, the run and its report): the ETA from the first
    with progress(args.repeats * len(trees), "launches", unit="launch") as bar:
        for i in range(args.repeats):
            for name, tree in trees.items():
                logs = work / f"{name}{i}"
                say(f"launch {i + 1}/{args.repeats} of {name} ({tree}), {args.duration:g} s ...")
                # redrawn as it samples, so the elapsed time moves during a launch
                r = run_launch(tree, args.profile, args.duration, logs, args.launch_args,
                               on_sample=bar.refresh)
                runs[name].append(r)
                (logs / "report.txt").write_text(r["report"])
                say(f"  {r['result']}  {r['robot']}")
                bar.update(1)
    figures: dict[str, Any] = {"profile": args.profile, "duration_s": args.duration,
                               "repeats": args.repeats}
    shares = {name: [share(r["per"]) for r in rs] for name, rs in runs.items()}
    names = sorted({n for rs in shares.values() for s in rs for n in s})
    rows = []
    for n in names:
        row: list[Any] = [n]
        for name in trees:
            vals = [s.get(n, 0.0) for s in shares[name]]
            v = sum(vals) / len(vals)
            figures[f"{name}_{n}_share"] = v
            row.append(f"{v:.3f}")
        if args.baseline:
            b, t = figures[f"baseline_{n}_share"], figures[f"this_{n}_share"]
            figures[f"{n}_ratio"] = t / b if b > 0 else float("nan")
            row.append(f"{t / b:.2f}" if b > 0 else "-")
        rows.append(row)
    for name in trees:
        tot = sum(sum(v for k, v in s.items() if k != PRECHECK)
                  for s in shares[name]) / len(shares[name])
        figures[f"{name}_total_share"] = tot
    head = ["process", *trees, *(["this / baseline"] if args.baseline else [])]
    rows.append(["total", *(f"{figures[f'{n}_total_share']:.3f}" for n in trees),
                 *([f"{figures['this_total_share'] / figures['baseline_total_share']:.2f}"]
                   if args.baseline else [])])
    print("\nCPU, share of one core (psutil: CPU seconds / seconds alive), mean of the repeats;"
          f" the total leaves out the {PRECHECK}")
    print_columns(head, rows)
    for name, rs in runs.items():
        for i, r in enumerate(rs):
            figures[f"{name}{i}_result"] = r["result"]
            figures[f"{name}{i}_robot"] = r["robot"]
    print_table("results", [(k, v) for k, v in figures.items() if k.endswith(("result", "robot"))])
    print(f"\nlogs and each tree's own `cassie report`: {work}/<tree><i>/")
    write_json(args.json, "launch", figures)
    if args.plot is not None:
        plot_shares(args.plot, figures, list(trees), names, args.baseline)
        print(f"plot: {args.plot}")
    return 0


def plot_shares(path: Path, figures: dict[str, Any], trees: list[str], names: list[str],
                baseline: str | None) -> None:
    """Bars of each process's CPU share per tree, the totals in the legend, the 1.6-core
    budget of two cores in the title (matplotlib, headless: a figure for the docs)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    x = np.arange(len(names))
    width = 0.8 / len(trees)
    fig, ax = plt.subplots(figsize=(9, 4.2))
    for i, tree in enumerate(trees):
        vals = [figures.get(f"{tree}_{n}_share", 0.0) for n in names]
        label = (f"{'baseline ' + baseline if tree == 'baseline' and baseline else tree}: "
                 f"total {figures[f'{tree}_total_share']:.2f} cores")
        ax.bar(x + (i - (len(trees) - 1) / 2) * width, vals, width, label=label)
    ax.set_xticks(x, [n.replace("_", "\n") for n in names])
    ax.set_ylabel("share of one core")
    ax.set_title("CPU per process, real-time launch of "
                 f"{figures['profile']} ({figures['duration_s']:g} s; budget: 1.6 of 2 cores)")
    ax.legend()
    ax.grid(axis="y", alpha=0.3)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    sys.exit(main())
