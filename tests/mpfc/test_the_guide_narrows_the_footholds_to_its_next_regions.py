"""The MPFC's side of the SLIP guide (processes.mpfc.guide): its footholds narrowed to those
near the guide's next contact regions, all of them where that leaves none, and nothing
changed without a fresh plan."""

from __future__ import annotations

import numpy as np
import pytest

from processes.mpfc.guide import GuidedFootholds, guided_footholds, separation_xy
from runtime.codecs import GUIDE_OK, GuidePlan, no_guide_plan
from runtime.geometry import Foothold

COUNT, MARGIN_M, MAX_AGE_S = 2, 0.1, 0.6


def _square(x: float, y: float = 0.0, side: float = 0.3) -> Foothold:
    h = 0.5 * side
    return Foothold.from_polygon(np.array([[x - h, y - h], [x + h, y - h], [x + h, y + h],
                                           [x - h, y + h]]))


def _row() -> list[Foothold]:
    """Five stones along x, 0.6 m apart (gaps of 0.3 m), and one off to the side."""
    return [_square(0.6 * i) for i in range(5)] + [_square(0.6, 1.0)]


def _plan(regions: list[Foothold], times: list[tuple[float, float]], utime_s: float = 0.0
          ) -> GuidePlan:
    """A plan with a step at the centre of each region, over ``times`` (sim s)."""
    pos = np.array([[*r.vertices_xy.mean(axis=0), 0.0] for r in regions]).reshape(-1, 3)
    k = len(regions)
    return GuidePlan(int(utime_s * 1e6), pos, np.array([a for a, _ in times]),
                     np.array([b for _, b in times]), np.arange(k) % 2, np.arange(k),
                     tuple(regions), np.array([0.4, 0.0]), GUIDE_OK)


def _narrow(footholds: list[Foothold], plan: GuidePlan | None, t: float) -> list[Foothold]:
    return guided_footholds(footholds, plan, t, COUNT, MARGIN_M, MAX_AGE_S)


def test_it_keeps_the_footholds_of_the_guides_next_regions() -> None:
    holds = _row()
    # (the plan's regions are copies: the MPFC's footholds are matched by place, not identity)
    plan = _plan([_square(0.6), _square(1.2), _square(2.4)],
                 [(0.0, 0.5), (0.4, 1.0), (1.2, 2.0)])
    kept = _narrow(holds, plan, 0.1)
    assert kept == [holds[1], holds[2]]  # the third step's region is the third
    assert all(any(k is h for h in holds) for k in kept)  # the objects, not copies
    # later, the first step over: the second and the third
    assert _narrow(holds, plan, 0.55) == [holds[2], holds[4]]
    # counted in regions, not in time: a step two seconds out still counts as the next
    later = _plan([_square(0.6), _square(2.4)], [(0.0, 3.0), (3.0, 4.0)])
    assert _narrow(holds, later, 0.1) == [holds[1], holds[4]]


def test_a_foothold_within_the_margin_of_a_region_is_kept_and_one_beyond_is_not() -> None:
    near, far = _square(0.65 + 0.3), _square(0.6 + 0.3 + MARGIN_M + 0.05)  # gaps 0.05, 0.15
    region = _square(0.6)
    assert separation_xy(near, region) == pytest.approx(0.05)
    assert separation_xy(region, region) < 0.0
    kept = _narrow([near, far], _plan([region], [(0.0, 1.0)]), 0.2)
    assert kept == [near]


def test_a_step_on_no_region_keeps_the_footholds_near_its_contact_point() -> None:
    holds = _row()
    plan = _plan([_square(1.2)], [(0.0, 1.0)])
    plan = GuidePlan(**{**plan.__dict__, "region": np.array([-1]), "regions": ()})
    assert _narrow(holds, plan, 0.0) == [holds[2]]


def test_when_nothing_is_near_the_guide_every_foothold_is_kept() -> None:
    holds = _row()
    plan = _plan([_square(5.0, 5.0)], [(0.0, 1.0)])
    assert _narrow(holds, plan, 0.0) is holds
    cached = GuidedFootholds(COUNT, MARGIN_M, MAX_AGE_S)
    assert cached.of(holds, plan, 0.0) is holds
    assert cached.fell_back and not cached.narrowed


@pytest.mark.parametrize("why", ["no plan", "a stale plan", "a plan from the future",
                                 "a plan-less message", "every step over"])
def test_without_a_fresh_plan_nothing_is_narrowed(why: str) -> None:
    holds = _row()
    plan: GuidePlan | None = {
        "no plan": None,
        "a stale plan": _plan([_square(0.6)], [(0.0, 5.0)], utime_s=0.0),
        "a plan from the future": _plan([_square(0.6)], [(0.0, 5.0)], utime_s=2.0),
        "a plan-less message": no_guide_plan(0, "no footholds yet"),
        "every step over": _plan([_square(0.6)], [(0.0, 0.5)], utime_s=0.5),
    }[why]
    t = 1.0
    assert _narrow(holds, plan, t) is holds
    cached = GuidedFootholds(COUNT, MARGIN_M, MAX_AGE_S)
    assert cached.of(holds, plan, t) is holds
    assert not cached.narrowed and not cached.fell_back


def test_the_narrowed_list_is_the_same_object_until_the_plan_or_its_next_steps_change(
        ) -> None:
    holds = _row()
    plan = _plan([_square(0.6), _square(1.2)], [(0.0, 0.5), (0.4, 1.0)])
    cached = GuidedFootholds(COUNT, MARGIN_M, MAX_AGE_S)
    first = cached.of(holds, plan, 0.1)
    assert cached.narrowed and first == [holds[1], holds[2]]
    assert cached.of(holds, plan, 0.2) is first  # the solver's per-list caches hold
    assert cached.of(holds, plan, 0.55) == [holds[2]]  # the first step over, one left
    again = _plan([_square(0.6), _square(1.2)], [(0.0, 0.5), (0.4, 1.0)])
    assert cached.of(holds, again, 0.1) is not first  # a new plan: looked at afresh


def test_the_guides_velocity_lengthens_to_reach_a_far_next_region_and_only_a_far_one() -> None:
    """``reaching_velocity``: at a chasm's edge (the next region 0.59 m ahead) one nominal
    step of T v reaches 5 cm into it, within the bound; a stone 0.4 m ahead (a gap the MPFC
    crosses alone) leaves the guide's velocity as it is; so does standing on the region."""
    from processes.mpfc.guide import reaching_velocity

    def rect(x0, x1):
        return Foothold.from_polygon(np.array([[x0, -1.0], [x1, -1.0], [x1, 1.0], [x0, 1.0]]))

    near, far, stone = rect(-2.0, 0.0), rect(0.59, 3.0), rect(0.4, 0.6)
    v = np.array([0.3, 0.0])
    out = reaching_velocity(v, (0.0, 0.0), [near, far], 0.4, 2.0, 0.55)
    np.testing.assert_allclose(out, [0.64 / 0.4, 0.0])
    out = reaching_velocity(v, (0.0, 0.0), [near, far], 0.4, 1.0, 0.55)  # the bound
    np.testing.assert_allclose(out, [1.0, 0.0])
    np.testing.assert_allclose(reaching_velocity(v, (0.0, 0.0), [near, stone], 0.4, 1.0, 0.55),
                               v)
    np.testing.assert_allclose(reaching_velocity(v, (1.0, 0.0), [far], 0.4, 1.0, 0.55), v)
    np.testing.assert_allclose(reaching_velocity(np.zeros(2), (0.0, 0.0), [far], 0.4, 1.0,
                                                 0.55), np.zeros(2))  # a stand stays one


def test_a_far_next_region_is_judged_from_the_region_underfoot_not_the_foot() -> None:
    """On a stone with the foot at its back edge the next stone 0.4 m beyond the stone is
    0.65 m from the foot: a gap the MPFC crosses alone, so the velocity stays."""
    from processes.mpfc.guide import reaching_velocity

    here, there = _square(0.0, side=0.3), _square(0.7, side=0.3)  # 0.4 m apart
    v = np.array([0.375, 0.0])
    np.testing.assert_allclose(reaching_velocity(v, (-0.1, 0.0), [here, there], 0.4, 1.0,
                                                 0.55), v)
