"""The MPFC process with ``guide: true``: a fresh guide plan narrows the footholds of its
solve and sets its desired velocity; a stale one, or none, leaves both as without the guide;
without the param the process has no guide input at all."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from runtime.codecs import GUIDE_OK, GuidePlan, footholds_from_msg, guide_plan_to_msg
from runtime.driver import NodeDriver
from sim import terrain as sim_terrain
from tests.conftest import one_process
from tests.slip_guide.test_the_guide_process_plans_from_the_state_over_the_footholds import (
    _state,
)

NOMINAL = (0.5, 0.05)


def _driver(tmp_path: Path, guide: bool = True) -> NodeDriver:
    params = {"footholds": "channel", "guide": guide}
    return NodeDriver.from_config(*one_process(tmp_path, "mpfc", params, mode="lockstep"))


def _guide(footholds_msg, utime: int):  # type: ignore[no-untyped-def]
    """A plan on the start platform and the nearest stone, at NOMINAL m/s."""
    holds = footholds_from_msg(footholds_msg)
    regions = sorted(holds, key=lambda f: float(np.linalg.norm(f.vertices_xy.mean(axis=0))))[:2]
    pos = np.array([[*r.vertices_xy.mean(axis=0), 0.0] for r in regions])
    t = utime * 1e-6
    return guide_plan_to_msg(GuidePlan(
        utime, pos, np.array([t, t + 0.5]), np.array([t + 0.6, t + 1.2]), np.array([0, 1]),
        np.array([0, 1]), tuple(regions), np.array(NOMINAL), GUIDE_OK))


def test_a_fresh_plan_narrows_the_footholds_and_sets_the_desired_velocity(tmp_path: Path
                                                                          ) -> None:
    truth = sim_terrain.foothold_set_msg(sim_terrain.generate("stones"))
    d = _driver(tmp_path)
    d.tick(state=_state(0.3, 100_000), footholds=truth, guide=_guide(truth, 50_000))
    plan, dbg = d.sent["plan"][-1], d.sent["debug"][-1]
    assert np.allclose(plan.desired_velocity, NOMINAL, atol=1e-6)  # (pelvis yaw 0)
    c = d.node.counters()
    assert (c["guided"], c["guide_narrowed"], c["guide_fallbacks"]) == (1, 1, 0)
    assert 1 <= dbg.num_footholds <= 3  # of 16 (the two regions and what touches them)
    assert plan.solve_status == 0


def test_a_stale_plan_leaves_the_solve_as_without_the_guide(tmp_path: Path) -> None:
    truth = sim_terrain.foothold_set_msg(sim_terrain.generate("stones"))
    for sub in ("a", "b"):
        (tmp_path / sub).mkdir()
    guided, plain = _driver(tmp_path / "a"), _driver(tmp_path / "b", guide=False)
    state = _state(0.3, 2_000_000)
    guided.tick(state=state, footholds=truth, guide=_guide(truth, 1_000_000))  # 1 s old
    plain.tick(state=state, footholds=truth)
    assert guided.node.counters()["guided"] == 0
    a, b = guided.sent["plan"][-1], plain.sent["plan"][-1]
    assert list(a.desired_velocity) == list(b.desired_velocity) == [0.375, 0.0]
    assert a.next_footstep_world == b.next_footstep_world
    assert guided.sent["debug"][-1].num_footholds == plain.sent["debug"][-1].num_footholds


def test_without_the_guide_param_the_mpfc_has_no_guide_input(tmp_path: Path) -> None:
    d = _driver(tmp_path, guide=False)
    assert "guide" not in d.node.inputs and "guide" not in d.ports
