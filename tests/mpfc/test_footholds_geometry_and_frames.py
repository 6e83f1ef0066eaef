"""The MPFC's foothold arrays: the stance frame transform, pruning and the height anchor (the
polygons themselves: tests/runtime/test_foothold_polygons_are_checked_and_round_trip...)."""

from __future__ import annotations

import numpy as np

from processes.footstep_search.footholds import WorldFootholds, yaw_rotation
from runtime.geometry import Foothold


def test_local_frame_rotates_and_translates_consistently() -> None:
    """A point in a foothold stays inside after mapping world -> stance frame."""
    rng = np.random.default_rng(2)
    fh = Foothold.from_polygon(np.array([[2, 1], [2.4, 1], [2.4, 1.5], [2, 1.5]], dtype=float),
                               normal=(0.05, -0.1, 1.0), offset=0.2)
    world = WorldFootholds([fh], 0.2)
    for _ in range(5):
        p_s = np.array([*rng.uniform(1.0, 2.0, 2), rng.uniform(-0.1, 0.1)])
        yaw = rng.uniform(-np.pi, np.pi)
        lf = world.local(p_s, yaw, 20, 3.0)
        p_w = np.array([2.2, 1.2, 0.0])
        p_w[2] = fh.height_at(p_w[:2])
        p_l = yaw_rotation(yaw).T @ (p_w - p_s)
        assert np.all(lf.F[0] @ p_l[:2] <= lf.c[0] + 1e-12)
        assert np.isclose(lf.alpha[0] + lf.beta[0] @ p_l[:2], p_l[2])
        a3, b3, n3, d3 = lf.three_d()
        real = np.isfinite(b3[0])
        assert np.all(a3[0][real] @ p_l <= b3[0][real] + 1e-12)
        assert np.isclose(n3[0] @ p_l, d3[0])


def test_pruning_keeps_the_nearest_within_distance() -> None:
    fhs = [Foothold.from_polygon(np.array([[x, 0], [x + 0.2, 0], [x + 0.2, 0.2], [x, 0.2]]))
           for x in (0.0, 0.5, 1.0, 3.0, -0.7)]
    steep = Foothold.from_polygon(np.array([[0, 0], [1, 0], [1, 1.0]]), normal=(1, 0, 0.05))
    world = WorldFootholds([*fhs, steep], 0.2)
    lf = world.local(np.array([0.1, 0.1, 0.0]), 0.0, 3, 2.0)
    assert list(lf.index) == [0, 1, 4]  # far one (index 3) and the steep one dropped
    lf = world.local(np.array([0.1, 0.1, 0.0]), 0.0, 10, 2.0)
    assert sorted(lf.index) == [0, 1, 2, 4]


def test_anchor_takes_heights_relative_to_the_foothold_under_the_stance_foot() -> None:
    """A state estimate 1.4 cm below the footholds' frame (vertical drift): without the
    anchor the next stone looks 1.4 cm higher than it is; with it, its height is relative to
    the stone the stance foot stands on, in the estimate's frame."""
    low = Foothold.from_polygon(np.array([[-0.2, -0.2], [0.2, -0.2], [0.2, 0.2], [-0.2, 0.2]]))
    high = Foothold.from_polygon(np.array([[0.3, -0.2], [0.6, -0.2], [0.6, 0.2], [0.3, 0.2]]),
                                 offset=0.15)
    world = WorldFootholds([low, high], 0.2)
    foot = np.array([0.0, 0.0, -0.014])  # on `low`, as the drifted estimate sees it
    absolute = world.local(foot, 0.0, 10, 2.0)
    anchored = world.local(foot, 0.0, 10, 2.0, anchor=0.05)
    i = list(anchored.index).index(1)
    assert np.isclose(absolute.alpha[i], 0.15 + 0.014)
    assert np.isclose(anchored.alpha[i], 0.15)  # the true rise from one stone to the next
    # a stance foot off every foothold (beyond the anchor distance) keeps absolute heights
    away = world.local(np.array([0.0, 0.5, -0.014]), 0.0, 10, 2.0, anchor=0.05)
    assert np.allclose(np.sort(away.alpha), np.sort(absolute.alpha))
