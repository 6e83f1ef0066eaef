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
