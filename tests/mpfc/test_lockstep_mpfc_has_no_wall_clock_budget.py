"""In lockstep (the deterministic harness, the lockstep launch) the MPFC search never stops on
the wall clock, so a busy machine cannot change a trial's result; in real time it keeps the
configured budget."""

from __future__ import annotations

import math

from runtime.builder import build_node
from runtime.config import HW_CONFIG_DIR, load_profile


def test_lockstep_profile_gives_the_search_no_wall_clock_budget():
    profile = load_profile(HW_CONFIG_DIR / "experiment.yaml")
    assert profile.mode == "lockstep"
    node = build_node(profile.processes["mpfc"], profile)
    assert math.isinf(node.solver.params.time_limit_ms)


def test_real_time_profile_keeps_the_configured_budget():
    profile = load_profile(HW_CONFIG_DIR / "sim.yaml")
    assert profile.mode == "realtime"
    node = build_node(profile.processes["mpfc"], profile)
    assert node.solver.params.time_limit_ms == 30.0
