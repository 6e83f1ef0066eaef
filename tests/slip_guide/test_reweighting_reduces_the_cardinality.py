"""Algorithm 1: the reweighted l1 iterations bring the cardinality (5) down from the plain
l1 solution's to at most two contacts per time step."""

from __future__ import annotations

import dataclasses

import pytest

from processes.slip_guide.planner import SlipPlanner
from tools.testbed.slip_scenes import problem, scene


@pytest.mark.parametrize("name", ["stones", "chasm", "stairs"])
def test_the_cardinality_falls_across_iterations_to_two(plan_of, name: str) -> None:
    plan = plan_of(name, 3.0)
    hist = plan.card_history
    assert len(hist) == plan.iterations >= 2
    assert hist[0] > 2  # the first QP (uniform l1) spreads the support
    assert hist[-1] <= 2 < hist[0]
    assert all(h > 2 for h in hist[:-1])  # Algorithm 1 stops at the first that meets (5)
    assert plan.stopped == "card"


def test_without_reweighting_the_plain_l1_plan_has_more_contacts(slip_params) -> None:
    p = dataclasses.replace(slip_params, rw_iterations=0)
    s_ref, v_ref, cands = problem(scene("stones", 0), p)
    plan = SlipPlanner(p).plan(s_ref[0], v_ref[0], s_ref, v_ref, cands)
    assert plan.iterations == 1
    assert plan.contacts_per_step.max() > 2


def test_a_reweighted_qp_without_a_solution_keeps_the_plan_before_it(slip_params) -> None:
    # measured: at k = 10, this chasm's third QP finds a time step over the gap whose
    # candidates the prefilter dropped once s~ moved; Algorithm 1 keeps alpha^{r-1}
    p = dataclasses.replace(slip_params, horizon_s=3.0, knn_k=10)
    s_ref, v_ref, cands = problem(scene("chasm", 2), p)
    plan = SlipPlanner(p).plan(s_ref[0], v_ref[0], s_ref, v_ref, cands)
    assert plan.stopped == "qp_infeasible"
    assert plan.status == "solved" and plan.iterations == len(plan.card_history) >= 1
    assert abs(plan.s[-1, 0] - s_ref[-1, 0]) <= p.path_tol_m + 1e-6
