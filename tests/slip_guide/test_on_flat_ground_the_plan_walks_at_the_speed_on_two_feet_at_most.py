"""On flat ground the plan follows v = 0.32 m/s within the path tolerance and, after
reweighting, uses at most two contacts at every time step; its steps alternate feet."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from processes.slip_guide.phases import assign_phases


@pytest.mark.parametrize("horizon_s", [1.5, 3.0, 4.5])
def test_the_com_tracks_the_speed_with_at_most_two_contacts(plan_of, slip_params,
                                                             horizon_s: float) -> None:
    plan = plan_of("flat", horizon_s)
    assert plan.status == "solved"
    assert plan.contacts_per_step.max() <= 2
    assert plan.contacts_per_step.min() >= 1  # no flight on flat ground at a walk
    speed = (plan.s[-1, 0] - plan.s[0, 0]) / horizon_s
    assert speed == pytest.approx(0.32, abs=0.1 / horizon_s)  # within the path tolerance
    assert np.abs(plan.s - plan.s_ref).max() <= slip_params.path_tol_m + 1e-6


def test_its_steps_are_merged_in_time_and_alternate_sides(plan_of, slip_params) -> None:
    plan = plan_of("flat", 4.5)
    steps = assign_phases(plan, slip_params.dt_s, slip_params.merge_radius_m)
    assert len(steps) >= 4
    assert max(s.duration_s for s in steps) >= 3 * slip_params.dt_s  # a stance, not impulses
    sides = [s.side for s in steps]
    assert all(a != b for a, b in itertools.pairwise(sides))
    xs = [s.position[0] for s in steps]
    assert xs == sorted(xs)  # walking forward
