"""``cassie experiment stones --sweep dmin=...``: real harness trials as jobs over the cores,
each written as it finishes, a second run of the same sweep running none again, and a JSON
and a PNG summary with both success rules per point."""

from __future__ import annotations

import json
from pathlib import Path

from tools.experiment import main as experiment_main
from tools.experiment.sweep import done_trials, frange


def test_the_grid_includes_both_ends() -> None:
    assert frange("0.35:0.70:0.05") == [0.35, 0.4, 0.45, 0.5, 0.55, 0.6, 0.65, 0.7]
    assert frange("0.4,0.6") == [0.4, 0.6]


def test_a_sweep_runs_each_trial_once_and_resumes(tmp_path: Path, capsys) -> None:
    args = ["stones", "--sweep", "dmin=0.5,0.6", "--trials", "1", "--duration", "0.6",
            "--jobs", "2", "--out", str(tmp_path)]
    assert experiment_main(args) == 0
    first = capsys.readouterr().out
    assert "ran 2 trial(s) now (0 were done before)" in first
    recs = done_trials(tmp_path / "trials.jsonl")
    assert len(recs) == 2
    assert sorted(r["point"][1] for r in recs.values()) == [0.5, 0.6]
    assert all(r["seed"] == 0 for r in recs.values())
    # a torn last line (a sweep killed while writing) is ignored, the rest kept
    with (tmp_path / "trials.jsonl").open("a") as f:
        f.write('{"key": "half')
    assert experiment_main(args) == 0
    assert "ran 0 trial(s) now (2 were done before)" in capsys.readouterr().out
    # a third point joins the sweep: only it runs, on a line of its own after the torn one
    assert experiment_main([*args[:2], "dmin=0.5,0.6,0.7", *args[3:]]) == 0
    assert "ran 1 trial(s) now (2 were done before)" in capsys.readouterr().out
    assert len(done_trials(tmp_path / "trials.jsonl")) == 3
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert [p["value"] for p in summary["points"]] == [0.5, 0.6, 0.7]
    assert all({"success_rate", "crossed_rate", "seeds"} <= set(p) for p in summary["points"])
    assert (tmp_path / "summary.png").stat().st_size > 10_000
