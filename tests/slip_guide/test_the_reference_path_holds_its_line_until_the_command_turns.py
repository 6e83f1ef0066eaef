"""``ReferenceLine``: the guide's reference path runs on a line fixed in the world, from the
CoM's foot on it, so that plans made as the robot wanders do not wander with it; it is laid
anew only on a turn beyond the threshold or a new speed."""

from __future__ import annotations

import math

import numpy as np
import pytest

from processes.slip_guide.process import ReferenceLine


def test_the_path_starts_at_the_coms_foot_on_a_line_held_through_small_heading_changes():
    line = ReferenceLine(math.radians(20.0))
    np.testing.assert_allclose(line.start(np.array([0.0, 0.0]), 0.0, 0.375), [0.0, 0.0])
    # the robot drifted 0.3 m left and turned 10 deg: the line stays y = 0
    np.testing.assert_allclose(line.start(np.array([1.0, 0.3]), math.radians(10.0), 0.375),
                               [1.0, 0.0])
    assert line.heading == 0.0 and line.relays == 1
    # a 30 deg turn lays a new line through the CoM
    np.testing.assert_allclose(line.start(np.array([2.0, 0.3]), math.radians(30.0), 0.375),
                               [2.0, 0.3])
    assert line.heading == pytest.approx(math.radians(30.0)) and line.relays == 2
    # on the new line from there: 1 m on in x is cos 30 deg along it
    p = line.start(np.array([3.0, 0.3]), math.radians(30.0), 0.375)
    u = np.array([math.cos(math.radians(30.0)), math.sin(math.radians(30.0))])
    np.testing.assert_allclose(p, np.array([2.0, 0.3]) + u[0] * u, atol=1e-12)
    # a new commanded speed (a stand: 0) lays it anew too
    line.start(np.array([3.0, 0.3]), math.radians(30.0), 0.0)
    assert line.relays == 3


def test_each_path_begins_at_the_com_and_comes_back_onto_the_line() -> None:
    s_ref = np.column_stack([np.arange(11) * 0.05, np.zeros(11), np.full(11, 0.85)])
    out, v = ReferenceLine.back_to_line(s_ref, np.array([0.0, 0.3]), 0.15, 1.0)
    np.testing.assert_allclose(out[0, :2], [0.0, 0.3])  # at the CoM
    np.testing.assert_allclose(out[7:, 1], 0.0)  # on the line from 1 s on (t = 1.05 s)
    assert np.all(np.diff(out[:8, 1]) < 0.0)  # coming back, no jump beyond 0.045 m a sample
    assert np.abs(np.diff(out[:, 1])).max() <= 0.3 * 0.15 + 1e-12
    np.testing.assert_allclose(out[:, [0, 2]], s_ref[:, [0, 2]])  # along the line unchanged
    np.testing.assert_allclose(v, np.diff(out, axis=0) / 0.15)


def test_candidates_beyond_the_corridor_across_the_line_are_left_out() -> None:
    from processes.slip_guide.candidates import Candidates

    line = ReferenceLine(math.radians(20.0))
    line.start(np.array([0.0, 0.0]), 0.0, 0.375)
    pts = np.array([[0.5, 0.0, 0.0], [1.0, 0.3, 0.0], [1.0, -0.7, 0.0], [2.0, 0.7, 0.0]])
    c = Candidates(pts, np.tile([0.0, 0.0, 1.0], (4, 1)), np.ones(4))
    kept = line.within(c, 0.35)
    np.testing.assert_allclose(kept.points, pts[:2])
    assert line.within(c, 0.0) is c  # 0: no corridor
