"""processes.mpfc.gait.Halt and foothold_ahead, with no LCM: at the end of a course (no
foothold within a step ahead) the gait stops, and it walks on where one appears."""

from __future__ import annotations

import numpy as np

from processes.mpfc.gait import Halt, foothold_ahead
from runtime.geometry import Foothold


def _rect(x0: float, x1: float, y0: float = -0.3, y1: float = 0.3) -> Foothold:
    return Foothold.from_polygon(np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]]))


def test_a_foothold_within_a_step_ahead_is_found_and_one_behind_or_beyond_reach_is_not(
) -> None:
    platform = _rect(-1.0, 0.03)  # the stance foot stands at its far edge
    assert not foothold_ahead([platform], (0.0, 0.0), (1.0, 0.0))
    assert foothold_ahead([platform, _rect(0.45, 0.8)], (0.0, 0.0), (1.0, 0.0))  # a stone
    assert not foothold_ahead([platform, _rect(0.75, 1.0)], (0.0, 0.0), (1.0, 0.0))  # too far
    assert foothold_ahead([platform], (0.0, 0.0), (-1.0, 0.0))  # walking back: the platform
    assert foothold_ahead([platform], (0.0, 0.0), (0.0, 0.0))  # no command: nothing to stop


def test_the_halt_stops_at_the_course_end_and_walks_on_when_a_foothold_appears() -> None:
    h, platform = Halt(), _rect(-1.0, 0.03)
    assert not h.update([platform, _rect(0.3, 0.6)], (0.0, 0.0), (1.0, 0.0))
    assert h.state == Halt.RUNNING
    assert h.update([platform], (0.0, 0.0), (1.0, 0.0)) and h.state == Halt.STOPPING
    assert not h.update([platform], (0.0, 0.0), (1.0, 0.0))  # (stays: no change to say)
    # it walks on once both feet in turn find a foothold ahead: two touchdowns in a row
    assert not h.update([platform, _rect(0.3, 0.6)], (0.0, 0.0), (1.0, 0.0))
    assert h.update([platform, _rect(0.3, 0.6)], (0.0, 0.0), (1.0, 0.0))
    assert h.state == Halt.RUNNING


def test_the_ground_underfoot_counts_only_where_it_goes_on_for_a_whole_step() -> None:
    """A platform ending 0.3 m ahead with nothing beyond: stop now, with room to brake, not
    at its edge; a long one (flat ground) or another foothold beyond goes on."""
    short = _rect(-1.0, 0.3)
    assert not foothold_ahead([short], (0.0, 0.0), (1.0, 0.0))
    assert foothold_ahead([_rect(-1.0, 5.0)], (0.0, 0.0), (1.0, 0.0))
    assert foothold_ahead([short, _rect(0.45, 0.8)], (0.0, 0.0), (1.0, 0.0))
    # a tread a step beyond the platform's edge, out of a step from the foot: walk to it
    assert foothold_ahead([short, _rect(0.72, 0.75)], (0.0, 0.0), (1.0, 0.0))
    assert not foothold_ahead([short, _rect(0.95, 1.2)], (0.0, 0.0), (1.0, 0.0))
    # standing off every foothold (a foot on an edge), the one ahead still counts
    assert foothold_ahead([_rect(0.1, 0.3)], (0.0, 0.0), (1.0, 0.0))


def test_only_the_swing_foots_side_beyond_the_crossover_margin_counts() -> None:
    """The right foot on a 7 cm beam face: the left foot, next to swing, must land 6 cm or
    more to its left, where there is no beam: stop (and the right foot's turn finds it)."""
    beam = _rect(0.0, 8.0, -0.035, 0.035)
    right_on_beam = (0.5, 0.03)
    assert not foothold_ahead([beam], right_on_beam, (1.0, 0.0), swing_side=1.0, margin_m=0.06)
    assert foothold_ahead([beam], right_on_beam, (1.0, 0.0))  # either side: it is there
    left_on_beam = (0.5, 0.03)
    assert foothold_ahead([beam], left_on_beam, (1.0, 0.0), swing_side=-1.0, margin_m=0.06)
    # a stone 30 cm to the swing side, a step ahead, is found
    assert foothold_ahead([_rect(-0.5, 0.1), _rect(0.3, 0.6, 0.25, 0.45)], (0.0, 0.0),
                          (1.0, 0.0), swing_side=1.0, margin_m=0.06)


def test_a_beam_too_narrow_for_both_feet_stops_the_gait_before_the_platforms_edge() -> None:
    """Two steps looked at: onto a 5 cm beam face the left foot could step, but the right
    foot then has nowhere 6 cm to its right; on a 13 cm face both find room."""
    platform = _rect(-1.0, 0.18, -0.7, 0.7)
    narrow, wide = _rect(0.42, 8.0, -0.025, 0.025), _rect(0.42, 8.0, -0.065, 0.065)
    right_foot = (-0.1, -0.13)  # 28 cm before the platform's edge, the left foot to swing
    assert not foothold_ahead([platform, narrow], right_foot, (1.0, 0.0), 1.0, 0.06)
    assert foothold_ahead([platform, wide], right_foot, (1.0, 0.0), 1.0, 0.06)


def test_beyond_the_maps_edge_nothing_found_is_not_a_reason_to_stop() -> None:
    """With perception the footholds end where the elevation map does: a stone whose next row
    lies past the map's edge walks on; the same stone with the map reaching past where the way
    must go on stops (and ground truth, no map, stops as before)."""
    stone = _rect(-0.15, 0.3, -0.15, 0.15)
    lo = np.array([-1.25, -1.25])
    assert not foothold_ahead([stone], (0.0, 0.0), (1.0, 0.0), 1.0, 0.06)
    assert foothold_ahead([stone], (0.0, 0.0), (1.0, 0.0), 1.0, 0.06, (lo, np.array([0.7, 1.0])))
    assert not foothold_ahead([stone], (0.0, 0.0), (1.0, 0.0), 1.0, 0.06,
                              (lo, np.array([1.2, 1.0])))
    h = Halt()
    assert not h.update([stone], (0.0, 0.0), (1.0, 0.0), 1.0, 0.06, (lo, np.array([0.7, 1.0])))
    assert h.state == Halt.RUNNING


def test_a_stop_is_left_only_for_a_way_that_goes_on_past_the_next_foothold() -> None:
    """Stopped on a stone with one more stone ahead and nothing past it: walking on would
    stop again on that stone, so the stop holds; with a third stone past it, it walks on.
    (Walking, one stone ahead is enough to go on.)"""
    here, next_, last = _rect(-0.15, 0.15), _rect(0.45, 0.75), _rect(1.05, 1.35)
    assert foothold_ahead([here, next_], (0.0, 0.0), (1.0, 0.0), 1.0, 0.06)
    assert not foothold_ahead([here, next_], (0.0, 0.0), (1.0, 0.0), 1.0, 0.06, beyond=True)
    assert foothold_ahead([here, next_, last], (0.0, 0.0), (1.0, 0.0), 1.0, 0.06, beyond=True)
    h = Halt()
    assert h.update([here], (0.0, 0.0), (1.0, 0.0), 1.0, 0.06) and h.state == Halt.STOPPING
    for _ in range(3):
        h.update([here, next_], (0.0, 0.0), (1.0, 0.0), 1.0, 0.06)
    assert h.state == Halt.STOPPING
    for _ in range(2):
        h.update([here, next_, last], (0.0, 0.0), (1.0, 0.0), 1.0, 0.06)
    assert h.state == Halt.RUNNING


def test_the_compiled_probe_pass_marks_exactly_the_probes_inside_each_foothold() -> None:
    """``_probe_hits`` (the look ahead's one compiled pass over footholds x probes) against
    ``Foothold.contains_xy`` point by point, on random convex footholds of 3-8 corners, and
    whether the stance point lies in each."""
    from processes.footstep_search.footholds import WorldFootholds
    from processes.mpfc.gait import _probe_hits

    rng = np.random.default_rng(7)
    holds = []
    for _ in range(12):
        c = rng.uniform(-1.0, 1.0, 2)
        ang = np.sort(rng.uniform(0.0, 2 * np.pi, rng.integers(3, 9)))
        r = rng.uniform(0.1, 0.5)
        holds.append(Foothold.from_polygon(c + r * np.c_[np.cos(ang), np.sin(ang)]))
    pts = rng.uniform(-1.5, 1.5, (4000, 2))
    stance = holds[3].vertices_xy.mean(axis=0)
    world = WorldFootholds(holds, -1.0)  # padded as the look ahead pads them
    assert list(world.index) == list(range(len(holds)))
    hits = np.zeros((len(holds), len(pts)), dtype=np.bool_)
    under = np.zeros(len(holds), dtype=np.bool_)
    _probe_hits(pts, stance, world.F, world.c, world.V.min(axis=1), world.V.max(axis=1), hits,
                under)
    for k, f in enumerate(holds):
        expected = np.array([f.contains_xy(x, y, 1e-9) for x, y in pts])
        assert np.array_equal(hits[k], expected), k
        assert under[k] == f.contains_xy(*stance, 1e-9)
    assert under[3] and hits.any(axis=1).all()
