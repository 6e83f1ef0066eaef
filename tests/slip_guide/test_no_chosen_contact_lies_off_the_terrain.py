"""Every contact a plan chooses lies on a foothold: none in the chasm's gap, none between
stepping stones, none off the stairs' treads; and every candidate was sampled on one."""

from __future__ import annotations

import numpy as np
import pytest

from processes.slip_guide.candidates import sample_footholds
from tools.testbed.slip_scenes import CHASM_GAP_M, scene


@pytest.mark.parametrize(("name", "trial"), [("chasm", 0), ("stones", 0), ("stones", 1),
                                             ("stairs", 0)])
def test_every_chosen_contact_is_on_a_foothold(plan_of, name: str, trial: int) -> None:
    plan = plan_of(name, 3.0, trial)
    assert plan.status == "solved"
    holds = scene(name, trial).footholds
    chosen = plan.positions[plan.chosen]
    assert len(chosen) > 0
    for p in chosen:
        assert any(f.contains(p, tol=1e-6) for f in holds), p


def test_the_chasm_is_crossed_without_a_contact_in_its_gap(plan_of) -> None:
    plan = plan_of("chasm", 4.5)
    x = plan.positions[plan.chosen, 0]
    assert not np.any((x > CHASM_GAP_M[0]) & (x < CHASM_GAP_M[1]))
    assert plan.s[-1, 0] > CHASM_GAP_M[1]  # and the CoM is past it
    assert x.max() > CHASM_GAP_M[1]


def test_the_grid_samples_lie_inside_their_footholds() -> None:
    holds = scene("stones", 2).footholds
    cands = sample_footholds(holds, 0.05, (-1.0, 4.0, -1.0, 1.0))
    assert len(cands) > 100
    inside = np.array([[f.contains(p, tol=1e-9) for f in holds] for p in cands.points])
    assert inside.any(axis=1).all()
    np.testing.assert_allclose(cands.normals[:, 2], 1.0)
