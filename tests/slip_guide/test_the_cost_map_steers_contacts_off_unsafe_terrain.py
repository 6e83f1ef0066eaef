"""The terrain cost map of (6): S3's safety score makes unsafe cells costly, and the plan's
contacts leave a strip S3 scores unsafe, which they use when it is not; elevation-map cells
become candidates with the map's heights and slopes."""

from __future__ import annotations

import dataclasses

import numpy as np

from processes.slip_guide.candidates import CostMap, sample_elevation_map, sample_footholds
from processes.slip_guide.planner import SlipPlanner
from tools.testbed.slip_scenes import problem, scene

STRIP_X_M = (0.35, 0.6)


def _score_map() -> CostMap:
    """A 4 m x 2 m map at 2 cm, safe but for the strip across the path."""
    x = -1.0 + 0.02 * np.arange(200)
    score = np.ones((100, 200))
    score[:, (x > STRIP_X_M[0]) & (x < STRIP_X_M[1])] = 0.0
    return CostMap(score, (-1.0, -1.0), 0.02)


def test_the_cost_is_one_on_safe_cells_and_high_on_unsafe_or_unknown_ones() -> None:
    cm = _score_map()
    xy = np.array([[0.0, 0.0], [0.5, 0.0], [9.0, 0.0]])  # safe, in the strip, off the map
    np.testing.assert_allclose(cm.cost_at(xy, 4.0), [1.0, 5.0, 5.0])


def test_contacts_avoid_the_unsafe_strip_they_use_without_the_cost_map(slip_params) -> None:
    p = dataclasses.replace(slip_params, horizon_s=3.0)
    sc = scene("flat", 0)
    s_ref, v_ref, plain = problem(sc, p)
    bounds = (-1.0, 2.0, -1.0, 1.0)
    costly = sample_footholds(sc.footholds, p.candidate_spacing_m, bounds, _score_map(), 20.0)
    planner = SlipPlanner(p)

    def in_strip(cands) -> int:
        plan = planner.plan(s_ref[0], v_ref[0], s_ref, v_ref, cands)
        assert plan.status == "solved"
        x = plan.positions[plan.chosen, 0]
        return int(np.sum((x > STRIP_X_M[0]) & (x < STRIP_X_M[1])))

    assert in_strip(plain) > 0
    assert in_strip(costly) == 0


def test_elevation_map_cells_are_candidates_with_their_height_and_slope() -> None:
    x = 0.05 * np.arange(40)
    elevation = np.tile(0.1 * x, (20, 1))  # a ramp rising 10 cm per metre along x
    elevation[5, 5] = np.nan  # unknown: no candidate
    score = np.ones_like(elevation)
    score[:, 30:] = 0.2  # below k_safe: no candidates
    c = sample_elevation_map(elevation, (0.0, 0.0), 0.05, score, k_safe=0.5)
    assert len(c) == 20 * 30 - 5  # the unknown cell and its 4 neighbours (slope unknown)
    np.testing.assert_allclose(c.points[:, 2], 0.1 * c.points[:, 0], atol=1e-12)
    np.testing.assert_allclose(c.normals, np.tile([-0.1, 0.0, 1.0], (len(c), 1))
                               / np.sqrt(1.01), atol=1e-9)
    np.testing.assert_allclose(c.cost, 1.0)
