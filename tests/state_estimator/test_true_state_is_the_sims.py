"""The paper's ground-truth-state runs (``cassie experiment --true-state``): the estimator
publishes the sim's own pose and velocity of the same step, and keeps its contact estimate."""

from __future__ import annotations

from typing import Any

import numpy as np

from runtime.config import HW_CONFIG_DIR
from tools.experiment.trials import run_trial


def test_the_published_state_is_the_sims_state_of_the_same_step():
    truth: dict[int, Any] = {}
    states: list[Any] = []
    nodes: dict[str, Any] = {}

    def setup(h: Any) -> None:
        nodes.update({b.node.name: b.node for b in h.bindings})
        h.tap("GROUND_TRUTH", lambda _t, m: truth.__setitem__(m.header.utime, m))
        h.tap("CASSIE_STATE", lambda _t, m: states.append(m))

    run_trial("flat", 0.5, 0, None, False, 0.375, HW_CONFIG_DIR / "experiment.yaml",
              setup=setup, true_state=True)
    assert len(states) > 900  # 2 kHz
    same = [s for s in states[1:] if s.header.utime in truth]
    assert len(same) >= len(states) - 2  # a truth for every step but the first ones
    for s in same[::50]:
        gt = truth[s.header.utime]
        np.testing.assert_array_equal(s.q, gt.q)
        np.testing.assert_array_equal(s.v, gt.v)
    assert nodes["state_estimator"].counters()["truth_stale"] <= 1
    assert any(any(s.in_contact) for s in states)  # the estimator's own contact flags
