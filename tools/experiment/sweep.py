"""Sweeps: many harness trials as independent jobs over the machine's cores.

A sweep is a grid of trial settings (a parameter's values x seeds). Each trial runs in a
worker process of a pool (``concurrent.futures.ProcessPoolExecutor``: the harness is one
process and deterministic, so trials in parallel give the same figures as one by one); every
finished trial is appended at once to ``OUT/trials.jsonl``, so a sweep stopped half-way and
started again with the same command runs only the trials not done yet. Seeds are fixed
(``--seed`` .. ``--seed + --trials - 1`` for every point) and recorded with each trial. At the
end: ``OUT/summary.json`` (per point: trials, success rate by the experiment's rule, the plain
"crossed without a fall" rate, falls, mean distance and speed) and ``OUT/summary.png``, both
rates against the swept value; and trials per hour on this machine.
"""

from __future__ import annotations

import json
import os
import time
from collections.abc import Callable, Sequence
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from tools.experiment.judge import Trial


@dataclass(frozen=True)
class TrialSpec:
    """One job of a sweep: what ``run_trial`` is called with."""

    name: str
    duration_s: float
    seed: int
    dmin: float | None
    perception: bool
    vx: float
    profile: str
    size: float | None = None  # the stairs' tread depth or the beam's width (courses)
    fixed_timing: bool = False  # the MPFC's step timing fixed (the paper's Fixed-T)
    lateral_gain: float = 0.0  # the operator's steering back onto the centre line, 1/s
    true_state: bool = False  # the controllers on the sim's true state (the paper's GT)
    planner: str = "mpfc"  # the footstep planner (tools.experiment.courses.PLANNERS)
    segmenter: str = "s3"  # the foothold extraction with perception (courses.SEGMENTERS)
    guide: bool = False  # the SLIP guide runs and the MPFC follows it
    #: the swept parameter's name and value (for the summary), e.g. ("dmin_m", 0.5)
    point: tuple[str, float] = ("", 0.0)

    def key(self) -> str:
        """What makes a trial the same trial when a sweep resumes."""
        fields: list[Any] = [self.name, self.duration_s, self.seed, self.dmin,
                             self.perception, self.vx, self.profile, self.size,
                             self.fixed_timing, self.lateral_gain]
        if self.true_state:  # (so the keys of sweeps run before it stay the same)
            fields.append("true_state")
        if self.planner != "mpfc":
            fields.append(self.planner)
        if self.segmenter != "s3":
            fields.append(self.segmenter)
        if self.guide:
            fields.append("guide")
        return json.dumps(fields, sort_keys=True)


@dataclass
class SweepResult:
    trials: list[dict[str, Any]] = field(default_factory=list)
    ran: int = 0  # trials run by this call (the rest were done before)
    wall_s: float = 0.0


def run_spec(spec: TrialSpec) -> dict[str, Any]:
    """A worker's job: one trial in the harness, as a JSON-able record."""
    from tools.experiment.trials import run_trial

    t0 = time.perf_counter()
    tr: Trial = run_trial(spec.name, spec.duration_s, spec.seed, spec.dmin, spec.perception,
                          spec.vx, Path(spec.profile), size=spec.size,
                          fixed_timing=spec.fixed_timing, lateral_gain=spec.lateral_gain,
                          true_state=spec.true_state, planner=spec.planner,
                          segmenter=spec.segmenter, guide=spec.guide)
    rec = {k: v for k, v in asdict(tr).items() if k not in ("timing", "cpu", "realtime")}
    rec.update(key=spec.key(), point=list(spec.point), worker_wall_s=time.perf_counter() - t0)
    return rec


def done_trials(path: Path) -> dict[str, dict[str, Any]]:
    """The trials already in ``path`` (one JSON object a line), by key; a torn last line (a
    sweep killed while writing) is ignored."""
    out: dict[str, dict[str, Any]] = {}
    if not path.exists():
        return out
    for line in path.read_text().splitlines():
        try:
            rec = json.loads(line)
        except json.JSONDecodeError:
            continue
        out[rec["key"]] = rec
    return out


def run_sweep(specs: Sequence[TrialSpec], out_dir: Path, jobs: int | None = None,
              worker: Callable[[TrialSpec], dict[str, Any]] = run_spec) -> SweepResult:
    """Every spec not done yet in ``out_dir/trials.jsonl``, ``jobs`` at a time (default: one
    per core), each appended as it finishes; a progress bar with an ETA on a terminal."""
    from tqdm import tqdm

    out_dir.mkdir(parents=True, exist_ok=True)
    log = out_dir / "trials.jsonl"
    done = done_trials(log)
    todo = [s for s in specs if s.key() not in done]
    if log.exists() and log.stat().st_size and not log.read_bytes().endswith(b"\n"):
        with log.open("a") as f:  # a torn last line: the next record starts on a line of its own
            f.write("\n")
    result = SweepResult()
    t0 = time.perf_counter()
    jobs = jobs or os.cpu_count() or 1
    with tqdm(total=len(specs), initial=len(specs) - len(todo), unit="trial", disable=None,
              desc="sweep") as bar, log.open("a") as f, ProcessPoolExecutor(jobs) as pool:
        pending = {pool.submit(worker, s) for s in todo}
        while pending:
            finished, pending = wait(pending, return_when=FIRST_COMPLETED)
            for fut in finished:
                rec = fut.result()
                f.write(json.dumps(rec) + "\n")
                f.flush()
                done[rec["key"]] = rec
                result.ran += 1
                bar.update(1)
    result.wall_s = time.perf_counter() - t0
    keys = {s.key() for s in specs}
    result.trials = [r for k, r in done.items() if k in keys]
    return result


def _fell_while_stopped(r: dict[str, Any]) -> bool:
    """``Trial.fell_while_stopped`` of a trial record (False for records made before it;
    records from before ``halt_speed_mps`` count every stop's speed as a walking one, and from
    before ``halt_feet_on_footholds`` both feet as on the course)."""
    from tools.experiment.judge import fell_in_a_stop

    return fell_in_a_stop(bool(r["fell"]), float(r["fall_time_s"]), float(r.get("halt_s", -1.0)),
                          bool(r.get("halt_on_foothold", True)),
                          float(r.get("halt_speed_mps", 0.0)),
                          bool(r.get("halt_feet_on_footholds", True)))


def summarise(trials: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """Per swept value: trials, success rate (the judge's rule, ``tools.experiment.judge``),
    crossed-without-a-fall rate, falls, and the mean distance and speed."""
    points: dict[tuple[str, float], list[dict[str, Any]]] = {}
    for r in trials:
        points.setdefault((str(r["point"][0]), float(r["point"][1])), []).append(r)
    rows = []
    for (name, value), rs in sorted(points.items(), key=lambda kv: kv[0][1]):
        n = len(rs)
        rows.append({
            "parameter": name, "value": value, "trials": n,
            "seeds": sorted(int(r["seed"]) for r in rs),
            "success_rate": sum(bool(r["success"]) for r in rs) / n,
            "crossed_rate": sum(bool(r["crossed"]) for r in rs) / n,
            "falls": sum(bool(r["fell"]) for r in rs),
            # falls with the MPFC stopped for no foothold within a step ahead, a step or more
            # before the fall (``Trial.fell_while_stopped``)
            "falls_halted": sum(_fell_while_stopped(r) for r in rs),
            "halts": sum(int(r.get("halts", 0)) for r in rs),
            "footsteps_outside": sum(int(r["footsteps_outside"]) for r in rs),
            "mean_distance_m": sum(float(r["distance_m"]) for r in rs) / n,
            "mean_velocity_mps": sum(float(r["mean_velocity_mps"]) for r in rs) / n,
        })
    return rows


def write_summary(rows: Sequence[dict[str, Any]], result: SweepResult, out_dir: Path,
                  title: str, jobs: int) -> Path:
    """``summary.json`` and ``summary.png`` (both rates against the swept value) in
    ``out_dir``; returns the plot's path."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    per_hour = 3600.0 * result.ran / result.wall_s if result.ran and result.wall_s > 0 else 0.0
    doc = {"title": title, "points": list(rows), "trials": len(result.trials),
           "ran_now": result.ran, "wall_s": round(result.wall_s, 1), "jobs": jobs,
           "trials_per_hour": round(per_hour, 1)}
    (out_dir / "summary.json").write_text(json.dumps(doc, indent=1) + "\n")
    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    xs = [r["value"] for r in rows]
    ax.plot(xs, [100 * r["success_rate"] for r in rows], "o-", label="success (our rule)")
    ax.plot(xs, [100 * r["crossed_rate"] for r in rows], "s--", label="crossed without a fall")
    ax.set_xlabel(rows[0]["parameter"] if rows else "")
    ax.set_ylabel("trials, %")
    ax.set_ylim(-5, 105)
    ax.set_title(title)
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    png = out_dir / "summary.png"
    fig.savefig(png, dpi=110)
    plt.close(fig)
    return png


def frange(text: str) -> list[float]:
    """``A:B:STEP`` (both ends included) or ``A,B,C`` as a list of values."""
    if ":" in text:
        a, b, step = (float(x) for x in text.split(":"))
        if step <= 0 or b < a:
            raise ValueError(f"{text!r}: want LO:HI:STEP with STEP > 0 and HI >= LO")
        n = round((b - a) / step)
        return [round(a + i * step, 10) for i in range(n + 1)]
    return [float(x) for x in text.split(",") if x.strip()]


def plot_sweeps(curves: Sequence[tuple[str, Path]], out_png: Path, title: str,
                rate: str = "success_rate") -> Path:
    """Several sweeps on one plot (the paper's Fig. 12: Opt-T and Fixed-T, GT and
    perception): ``rate`` (``success_rate`` or ``crossed_rate``) of each sweep folder's
    trials against the swept value, with Wilson 95 % intervals (a point of 20 trials at 90 %
    is +-13 %: a reader should see which differences are noise) and the trials per point in
    the legend."""
    import matplotlib
    from scipy.stats import binomtest

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    for label, folder in curves:
        rows = summarise(list(done_trials(Path(folder) / "trials.jsonl").values()))
        if not rows:
            continue
        ns = sorted({int(r["trials"]) for r in rows})
        per = f"{ns[0]}" if len(ns) == 1 else f"{ns[0]}-{ns[-1]}"
        # Wilson score intervals (scipy's)
        cis = [binomtest(round(r[rate] * r["trials"]), r["trials"]).proportion_ci(
            0.95, method="wilson") for r in rows]
        band = np.array([(ci.low, ci.high) for ci in cis])  # (P, 2)
        y = np.array([r[rate] for r in rows])
        ax.errorbar([100 * r["value"] for r in rows], 100 * y,
                    yerr=100 * np.array([y - band[:, 0], band[:, 1] - y]), fmt="o-",
                    capsize=3, label=f"{label} ({per} per point)")
    ax.set_xlabel("d_min [cm]" if "dmin" in title else "swept value [cm]")
    ax.set_ylabel(("success" if rate == "success_rate" else "crossed without a fall")
                  + " [%]")
    ax.set_ylim(-5, 105)
    ax.set_title(title)
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    out_png.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out_png, dpi=110)
    plt.close(fig)
    return out_png


def main(argv: list[str] | None = None) -> int:
    """``python -m tools.experiment.sweep OUT.png LABEL=DIR ...``: sweeps on one plot."""
    import argparse

    ap = argparse.ArgumentParser(prog="python -m tools.experiment.sweep",
                                 description="several sweeps' rates on one plot")
    ap.add_argument("out", type=Path, help="the PNG to write")
    ap.add_argument("curves", nargs="+", metavar="LABEL=DIR", help="a sweep folder per curve")
    ap.add_argument("--title", default="stepping stones: success against dmin")
    ap.add_argument("--rate", choices=("success_rate", "crossed_rate"), default="success_rate")
    args = ap.parse_args(argv)
    curves = []
    for c in args.curves:
        label, sep, folder = c.partition("=")
        if not sep or not (Path(folder) / "trials.jsonl").is_file():
            ap.error(f"{c!r}: want LABEL=DIR with DIR/trials.jsonl")
        curves.append((label, Path(folder)))
    print(plot_sweeps(curves, args.out, args.title, args.rate))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
