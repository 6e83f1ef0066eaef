"""Plans of the Table I scenes shared by the SLIP guide's tests (each a few tens of ms)."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import pytest

from processes.slip_guide.params import SlipParams
from processes.slip_guide.planner import SlipPlan, SlipPlanner
from runtime.config import HW_CONFIG_DIR
from runtime.params import load
from tools.testbed.slip_scenes import problem, scene


@pytest.fixture(scope="session")
def slip_params() -> SlipParams:
    """The gains file's parameters."""
    return load(SlipParams, HW_CONFIG_DIR / "gains" / "slip_guide.yaml")


@pytest.fixture(scope="session")
def plan_of(slip_params: SlipParams) -> Callable[..., SlipPlan]:
    """``plan_of(scene, horizon_s, trial)``: that scene's plan, computed once."""
    cache: dict[tuple[str, float, int], SlipPlan] = {}

    def plan(name: str, horizon_s: float = 3.0, trial: int = 0) -> SlipPlan:
        key = (name, horizon_s, trial)
        if key not in cache:
            p = dataclasses.replace(slip_params, horizon_s=horizon_s)
            s_ref, v_ref, cands = problem(scene(name, trial), p)
            cache[key] = SlipPlanner(p).plan(s_ref[0], v_ref[0], s_ref, v_ref, cands)
        return cache[key]

    return plan
