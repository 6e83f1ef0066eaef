"""The hand-over to standing waits until the CoM leaves every foot a share of the weight.

Traced on stones with perception (d_min 40 cm, seed 2016): a stop's step back put the front
foot under the CoM, the feet 14 cm apart fore-aft and 10 cm across. The CoM was inside the
box of the four contact points (the old rule, 2 cm margin) but over the front blade's toe;
the standing QP put the weight on the front foot, the rear foot unloaded, slid off its stone
and Cassie fell 2 s later. ``support_share`` is the weight every contact point can carry with
the centre of pressure at a point; the hand-over asks 5 % of it at the CoM and the capture
point.
"""

from __future__ import annotations

import math

import pytest

from processes.osc.controller import STAND_MIN_SHARE, support_share

# Cassie's blades: the contact points 6 cm ahead of and 10 cm behind the foot's centre
TOE, HEEL = 0.06, -0.10


def blades(left_xy: tuple[float, float], right_xy: tuple[float, float]) -> list[tuple]:
    """The four contact points (left front, left rear, right front, right rear) of feet
    facing +x with their centres at the given points."""
    return [(left_xy[0] + TOE, left_xy[1], 0.0), (left_xy[0] + HEEL, left_xy[1], 0.0),
            (right_xy[0] + TOE, right_xy[1], 0.0), (right_xy[0] + HEEL, right_xy[1], 0.0)]


def test_the_share_is_a_quarter_at_the_centre_and_zero_on_the_edge():
    square = [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)]
    assert support_share(square, (0.5, 0.5)) == pytest.approx(0.25)
    assert support_share(square, (0.0, 0.5)) == pytest.approx(0.0)
    assert support_share(square, (0.75, 0.5)) == pytest.approx(0.125)
    assert support_share(square, (2.0, 0.5)) < 0.0  # outside: no way to carry it


def test_points_on_a_line_carry_nothing():
    assert support_share([(0.0, 0.0), (1.0, 0.0), (2.0, 0.0), (3.0, 0.0)], (1.0, 0.0)) < 0.0


def test_side_by_side_feet_allow_the_com_a_few_centimetres_fore_and_aft():
    pts = blades((0.0, 0.135), (0.0, -0.135))
    centre = (0.5 * (TOE + HEEL), 0.0)
    assert support_share(pts, centre) == pytest.approx(0.25)
    ok = (centre[0] + 0.06, 0.0)  # 6 cm ahead of the feet's centre: still standing
    assert support_share(pts, ok) >= STAND_MIN_SHARE
    assert support_share(pts, (centre[0] + 0.075, 0.0)) < STAND_MIN_SHARE


def test_the_traced_stop_with_the_com_over_the_front_toe_is_refused():
    # the state at the traced hand-over (world x, y, m): left foot ahead, right behind
    pts = blades((2.095, 0.092), (1.950, -0.008))
    com = (2.122, 0.049)
    xs = [p[0] for p in pts]
    inside_box = min(xs) + 0.02 < com[0] < max(xs) - 0.02
    assert inside_box  # what the old rule asked: it handed over here
    assert support_share(pts, com) < STAND_MIN_SHARE
    # the same feet with the CoM half-way between them: standing is fine
    mid = (0.5 * (2.095 + 1.950) + 0.5 * (TOE + HEEL), 0.5 * (0.092 - 0.008))
    assert support_share(pts, mid) > 0.2


def test_the_share_does_not_depend_on_the_feet_heading():
    pts = blades((0.0, 0.135), (0.05, -0.135))
    p = (0.02, 0.03)
    a = 0.7
    c, s = math.cos(a), math.sin(a)
    turned = [(c * x - s * y, s * x + c * y, 0.0) for x, y, _ in pts]
    assert support_share(turned, (c * p[0] - s * p[1], s * p[0] + c * p[1])) == pytest.approx(
        support_share(pts, p))


def test_several_points_share_one_hull_and_get_the_least_share():
    pts = blades((2.095, 0.092), (1.950, -0.008))
    com, cp = (2.122, 0.049), (2.03, 0.04)
    assert support_share(pts, com, cp) == pytest.approx(
        min(support_share(pts, com), support_share(pts, cp)))
