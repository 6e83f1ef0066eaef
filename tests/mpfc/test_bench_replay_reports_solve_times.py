"""`cassie bench mpfc --closed-loop` replays recorded solves and reports their times."""

from __future__ import annotations

import numpy as np

from processes.mpfc.problem import MpfcModel
from tools.benchmarks.mpfc import replay
from tools.testbed.mpfc_instances import random_instance


def test_replay_reports_the_solve_time_figures_of_the_recorded_episodes(params):
    rng = np.random.default_rng(5)
    model = MpfcModel(params)
    episodes = [[random_instance(rng, model, m) for m in (3, 8)] for _ in range(2)]
    figs = replay(params, episodes)
    assert figs["closed_loop_solves"] == 4 and figs["closed_loop_solve_count"] == 4
    for stat in ("mean", "median", "p99", "p999", "max"):
        assert figs[f"closed_loop_solve_{stat}_ms"] > 0.0, stat
    assert sum(figs[f"closed_loop_status_{s}_count"]
               for s in ("optimal", "time_limited", "infeasible")) == 4
