"""A kill of the MPFC mid-walk does not end in a fall (issue faults 5): once its plans are
0.1 s old the OSC plans its own steps in place (``osc.fallback``) until the MPFC is back in
step with the robot; the 6 s it is gone is what a restart of the process takes. The process
that comes back is a new one: the node's state is built afresh, as a restart builds it."""

from __future__ import annotations

import dataclasses
from typing import Any

import pytest

from runtime.builder import build_node
from runtime.config import HW_CONFIG_DIR, load_profile
from runtime.harness import Harness
from runtime.node import HEALTH_OK

pytestmark = pytest.mark.faults

KILL_S, BACK_S, END_S = 2.0, 8.0, 12.0


@pytest.fixture(scope="module")
def run() -> dict[str, Any]:
    profile = load_profile(HW_CONFIG_DIR / "experiment.yaml")
    h = Harness.from_profile(profile)
    nodes = {b.node.name: b.node for b in h.bindings}
    mpfc, osc, sim = nodes["mpfc"], nodes["osc"], nodes["sim"]
    tick = mpfc.tick
    restarted: list[float] = []

    def dead_for_a_while(ctx: Any, inbox: Any) -> None:
        t = ctx.now_utime * 1e-6
        if KILL_S <= t < BACK_S:  # killed: no plans
            return
        if t >= BACK_S and not restarted:  # a new process: every bit of its state built anew
            fresh = build_node(profile.processes["mpfc"], dataclasses.replace(
                profile, mode="lockstep"))
            mpfc.__dict__.update(fresh.__dict__)
            restarted.append(t)
        tick(ctx, inbox)

    mpfc.tick = dead_for_a_while
    modes: list[tuple[float, int, str]] = []
    h.tap("OSC_TORQUE", lambda t, m: modes.append((t * 1e-6, int(m.mode), m.status)))
    walked: dict[float, float] = {}
    for t in (KILL_S, BACK_S, END_S):
        h.run_until(round(t * 1e6))
        walked[t] = sim.counters()["walked_m"]
    h.close()
    return {"modes": modes, "walked": walked, "sim": sim, "osc": osc}


def test_no_fall_and_never_safe_mode(run):
    assert run["sim"].health() == HEALTH_OK, run["sim"].status()
    assert all(m != 2 for _, m, _ in run["modes"]), "the OSC went to safe mode"
    assert run["osc"].counters()["plan_fallbacks"] == 1
    assert run["osc"].counters()["plan_handbacks"] == 1


def test_it_steps_in_place_while_the_mpfc_is_gone(run):
    during = [st for t, _, st in run["modes"] if KILL_S + 0.2 < t < BACK_S]
    assert during and all("MPFC plans lost" in st for st in during)
    w = run["walked"]
    assert w[BACK_S] - w[KILL_S] < 0.5  # stopped: the steps in place


def test_the_mpfc_gets_the_robot_back_and_it_walks_on(run):
    after = [(m, st) for t, m, st in run["modes"] if t > END_S - 1.0]
    assert after and all(m == 0 and "MPFC plans lost" not in st for m, st in after)
    w = run["walked"]
    assert w[END_S] - w[BACK_S] > 0.6  # walking again (measured 1.10 m in 4 s)
