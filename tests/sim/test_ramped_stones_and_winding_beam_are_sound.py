"""QuadPiPS' two courses (sim.terrain): ramped stones are Table I's stones with each top tilted
within the limit and its foothold on the tilted top; the winding beam is one connected surface
from platform to platform, its segments' headings and turns within their limits, its end
where the experiment's judge looks for it."""

from __future__ import annotations

import itertools
import math

import mujoco
import numpy as np
import pytest

from sim import terrain
from tools.experiment.courses import course_end_x


@pytest.mark.parametrize("seed", [0, 3])
def test_ramped_stones_are_table_i_stones_tilted_within_the_limit_with_footholds_on_the_tops(
        seed: int) -> None:
    limit = 12.0
    flat, ramped = terrain.stones(0.4, seed), terrain.ramped_stones(0.4, seed, limit)
    assert ramped.boxes == terrain.ramped_stones(0.4, seed, limit).boxes  # seeded
    assert len(ramped.boxes) == len(flat.boxes) == len(ramped.footholds) == 17
    stones = ramped.boxes[1:-1]
    tilts = np.degrees([(b.pitch, b.roll) for b in stones])
    np.testing.assert_allclose(tilts, ramped.params["tilts_deg"])
    assert np.all(np.abs(tilts) <= limit) and np.abs(tilts).max() > 0.5 * limit
    for a, b, f in zip(flat.boxes[1:-1], stones, ramped.footholds[1:-1], strict=True):
        # the same stone, its top's centre where Table I put it
        top = np.array(b.center) + 0.5 * b.size[2] * b.top_normal
        np.testing.assert_allclose(top, [*a.center[:2], a.top_z], atol=1e-12)
        assert b.size == a.size
        # the foothold lies on the tilted top: its plane is the top's, its corners on the top
        np.testing.assert_allclose(f.normal, b.top_normal, atol=1e-12)
        corners = b.top_corners()
        np.testing.assert_allclose(corners @ f.normal, f.offset, atol=1e-12)
        assert math.degrees(math.acos(f.normal[2])) <= math.hypot(limit, limit)
        for p in f.vertices:  # inside the top, 2 cm in, and what the judge's height says
            assert terrain.Terrain("t", boxes=(b,), ground_z=None).height_at(*p[:2]) == \
                pytest.approx(p[2], abs=1e-12)
        centre_xy = top[:2]
        assert f.contains_xy(*centre_xy)
        assert f.height_at(centre_xy) == pytest.approx(top[2], abs=1e-12)
    # the platforms stay level, the course ends where the stones' does
    assert not ramped.boxes[0].tilted and not ramped.boxes[-1].tilted
    assert course_end_x(ramped) == course_end_x(flat) is not None


def test_a_boxs_quaternion_turns_it_as_its_rotation_does() -> None:
    box = terrain.Box((0.0, 0.0, 0.0), (1.0, 1.0, 1.0), yaw=0.7, pitch=-0.2, roll=0.15)
    mat = np.zeros(9)
    mujoco.mju_quat2Mat(mat, np.array(box.quat_wxyz))
    np.testing.assert_allclose(mat.reshape(3, 3), box.rotation, atol=1e-12)
    assert np.linalg.norm(box.quat_wxyz) == pytest.approx(1.0)


@pytest.mark.parametrize("seed", [0, 1, 2, 7])
def test_the_winding_beam_is_connected_end_to_end_with_its_turns_within_their_limits(
        seed: int) -> None:
    t = terrain.winding_beam(width=0.23, segments=6, turn_min_deg=20.0, turn_max_deg=30.0,
                             max_heading_deg=30.0, seed=seed)
    headings = np.array(t.params["headings_deg"])
    turns = np.abs(np.diff(np.concatenate(([0.0], headings))))
    assert len(headings) == 6 and np.all(np.abs(headings) <= 30.0)
    assert np.all((turns >= 20.0) & (turns <= 30.0))
    assert np.any(np.diff(headings) > 0) and np.any(np.diff(headings) < 0)  # left and right
    path = np.array(t.path)
    pieces = np.diff(path, axis=0)
    np.testing.assert_allclose(np.degrees(np.arctan2(pieces[1:-1, 1], pieces[1:-1, 0])),
                               headings, atol=1e-9)
    # every point of the beam's strip, platform to platform, is on a top (the pit is -0.5 m)
    for a, d in zip(path[:-1], pieces, strict=True):
        u = d / np.linalg.norm(d)
        for s in np.linspace(0.0, 1.0, 41):
            for side in (-0.49, 0.0, 0.49):
                p = a + s * d + side * t.params["width"] * np.array((-u[1], u[0]))
                assert t.height_at(*p) == 0.0, (p, s, side)
    # each segment's centre line is on a foothold the judge checks (less the 2 cm margin at
    # its ends, as where the straight beam meets its platforms), and the end is the platform's
    for a, b in itertools.pairwise(path[1:-1]):
        for s in np.linspace(0.1, 0.9, 9):
            assert any(f.contains_xy(*(a + s * (b - a))) for f in t.landing_surfaces)
    end = t.boxes[-1]
    assert course_end_x(t) == pytest.approx(path[-2, 0]) == pytest.approx(
        end.center[0] - 0.5 * end.size[0])
    assert terrain.winding_beam(seed=seed).boxes == terrain.winding_beam(seed=seed).boxes


@pytest.mark.parametrize(("seed", "width"), [(0, 0.35), (3, 0.35), (1, 0.23)])
def test_the_winding_beams_footholds_for_the_foot_run_along_it_joints_included(
        seed: int, width: float) -> None:
    """Shrunk for a foot facing along each piece (``foot_headings``), the footholds leave no
    gap at a joint wider than 3 cm of the centre line, and a foot centred anywhere in one,
    turned to its heading, stands wholly on a top (without the joints' own footholds, a foot
    facing +x left ~20 cm gaps at every joint)."""
    half = (0.10, 0.02)
    t = terrain.generate("winding_beam", foot_half_size=half, width=width, seed=seed)
    assert len(t.foot_headings) == len(t.footholds)
    path = np.array(t.path)
    covered = []
    for a, b in itertools.pairwise(path[1:-1]):
        for s in np.linspace(0.0, 1.0, 101):
            p = a + s * (b - a)
            covered.append(any(f.contains_xy(*p) for f in t.footholds))
    gaps = [len(list(g)) for on, g in itertools.groupby(covered) if not on]
    assert max(gaps, default=0) <= 3, gaps  # 1 cm apart
    rng = np.random.default_rng(seed)
    for f, yaw in zip(t.footholds, t.foot_headings, strict=True):
        u, n = np.array((math.cos(yaw), math.sin(yaw))), np.array((-math.sin(yaw),
                                                                     math.cos(yaw)))
        v = f.vertices_xy
        for w in rng.dirichlet(np.ones(len(v)), size=20):
            c = w @ v  # a point inside the convex foothold
            for sx, sy in itertools.product((-1.0, 1.0), repeat=2):
                corner = c + sx * half[0] * u + sy * half[1] * n
                assert t.height_at(*corner) == 0.0, (c, yaw)
