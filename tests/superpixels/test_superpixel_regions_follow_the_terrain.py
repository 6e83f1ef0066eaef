"""QuadPiPS' superpixel planar regions (processes.superpixels) on synthetic elevation maps:
polygons on each flat surface at its height and within it, none on a slope steeper than the
limit, never over an unknown or unusable cell, convex, and the same for the same map."""

from __future__ import annotations

import numpy as np
import pytest

from processes.superpixels import SuperpixelParams, SuperpixelSegmenter
from processes.superpixels.segmenter import normals
from runtime.config import HW_CONFIG_DIR
from runtime.params import load

RES = 0.025
ORIGIN = np.array([-1.25, -1.25])
P = load(SuperpixelParams, HW_CONFIG_DIR / "gains" / "superpixels.yaml")


@pytest.fixture(scope="module")
def seg() -> SuperpixelSegmenter:
    return SuperpixelSegmenter(P)


def _grid(n: int = 100) -> tuple[np.ndarray, np.ndarray]:
    """World x, y of the cell centres of an n x n map at ORIGIN."""
    return np.meshgrid(ORIGIN[0] + np.arange(n) * RES, ORIGIN[1] + np.arange(n) * RES)


def _cells_inside(f, x: np.ndarray, y: np.ndarray) -> np.ndarray:  # type: ignore[no-untyped-def]
    """Cells whose centre lies in the foothold's horizontal polygon."""
    a, b = f.halfspaces_xy
    pts = np.column_stack((x.ravel(), y.ravel()))
    return np.all(pts @ a.T <= b + 1e-9, axis=1).reshape(x.shape)


def test_normals_of_a_plane_are_its_normal_eqs_5_to_9():
    x, y = _grid(20)
    n = normals(0.3 * x - 0.1 * y + 0.05, RES)
    want = np.array([-0.3, 0.1, 1.0]) / np.sqrt(1.1)
    np.testing.assert_allclose(n.reshape(-1, 3), np.tile(want, (400, 1)), atol=1e-9)


def test_two_flat_blocks_at_different_heights_give_polygons_on_both_planes_within_them(seg):
    x, y = _grid()
    e = np.where(x < 0.0, 0.0, 0.15)  # a 15 cm step along x = 0
    r = seg.segment(e, RES, ORIGIN)
    low = [f for f in r.footholds if f.vertices_xy[:, 0].max() < 0.0]
    high = [f for f in r.footholds if f.vertices_xy[:, 0].min() > 0.0]
    assert len(low) >= 10 and len(high) >= 10
    assert len(low) + len(high) == len(r.footholds)  # none spans the step
    for group, z in ((low, 0.0), (high, 0.15)):
        for f in group:
            np.testing.assert_allclose(f.normal, [0.0, 0.0, 1.0], atol=1e-9)
            for corner in f.vertices_xy:
                assert f.height_at(corner) == pytest.approx(z, abs=1e-9)
    # together they cover most of each block (the margin at the step and the map's edge aside)
    covered = np.zeros(x.shape, bool)
    for f in r.footholds:
        covered |= _cells_inside(f, x, y)
    assert covered[x < -0.1].mean() > 0.8 and covered[x > 0.1].mean() > 0.8


def test_a_slope_steeper_than_the_limit_gives_no_foothold_and_a_gentle_one_does(seg):
    x, _ = _grid()
    limit = np.degrees(np.arccos(P.min_normal_z))
    steep = np.tan(np.radians(limit + 5.0)) * x
    assert seg.segment(steep, RES, ORIGIN).footholds == []
    gentle = np.tan(np.radians(limit - 15.0)) * x
    found = seg.segment(gentle, RES, ORIGIN).footholds
    assert len(found) >= 10
    want = np.array([-np.tan(np.radians(limit - 15.0)), 0.0, 1.0])
    for f in found:  # each polygon lies on the slope's plane
        np.testing.assert_allclose(f.normal, want / np.linalg.norm(want), atol=1e-6)
        assert f.height_at(f.vertices_xy.mean(axis=0)) == pytest.approx(
            want[0] * -f.vertices_xy.mean(axis=0)[0], abs=1e-6)


def test_unknown_and_unusable_cells_are_never_inside_a_polygon(seg):
    x, y = _grid()
    rng = np.random.default_rng(3)
    e = 0.004 * rng.standard_normal(x.shape)  # flat floor with 4 mm noise
    e[(np.abs(x) < 0.6) & (np.abs(y) < 0.6) & ~((x > 0.0) & (np.abs(y) < 0.3))] = np.nan  # a U
    for r0, c0 in rng.integers(5, 95, size=(12, 2)):  # small holes, one to three cells
        e[r0:r0 + rng.integers(1, 4), c0:c0 + rng.integers(1, 4)] = np.nan
    e[70:80, 10:20] = 0.3  # a box: its edges are unsteppable
    r = seg.segment(e, RES, ORIGIN)
    assert len(r.footholds) >= 20
    for f in r.footholds:
        inside = _cells_inside(f, x, y)
        assert inside.any()
        assert np.isfinite(e[inside]).all()
        assert r.safe_mask[inside].all()  # only cells that passed the health check


def test_the_polygons_are_convex_at_least_a_foot_in_area_and_each_on_one_stone(seg):
    x, y = _grid()  # 16 stones 44 cm square, 16 cm gaps of unknown, tops +-10 cm and tilted
    e = np.full(x.shape, np.nan)
    rng = np.random.default_rng(1)
    for cx in (-0.9, -0.3, 0.3, 0.9):
        for cy in (-0.9, -0.3, 0.3, 0.9):
            top = (np.abs(x - cx) < 0.22) & (np.abs(y - cy) < 0.22)
            e[top] = rng.uniform(-0.1, 0.1) + 0.05 * (x[top] - cx)
    r = seg.segment(e, RES, ORIGIN)
    assert len(r.footholds) >= 16  # every stone holds at least one
    for f in r.footholds:
        v = f.vertices_xy
        edges = np.roll(v, -1, axis=0) - v
        turns = edges[:, 0] * np.roll(edges, -1, axis=0)[:, 1] - \
            edges[:, 1] * np.roll(edges, -1, axis=0)[:, 0]
        assert np.all(turns > -1e-12)  # every corner turns left: convex, counter-clockwise
        assert f.area_m2 >= P.min_area_m2
        # one stone each: the polygon's corners are all on one top
        tops = {(round(cx / 0.6 + 0.5), round(cy / 0.6 + 0.5)) for cx, cy in v}
        assert len(tops) == 1


def test_the_same_map_gives_the_same_footholds(seg):
    x, _ = _grid()
    rng = np.random.default_rng(7)
    e = np.where(x < 0.2, 0.0, 0.1) + 0.006 * rng.standard_normal(x.shape)
    e[rng.random(x.shape) < 0.02] = np.nan
    a = seg.segment(e, RES, ORIGIN)
    b = SuperpixelSegmenter(P).segment(e.copy(), RES, ORIGIN)
    assert len(a.footholds) == len(b.footholds) > 0
    for fa, fb in zip(a.footholds, b.footholds, strict=True):
        np.testing.assert_array_equal(fa.vertices_xy, fb.vertices_xy)
        np.testing.assert_array_equal(fa.normal, fb.normal)
        assert fa.offset == fb.offset
    np.testing.assert_array_equal(a.labels, b.labels)


def test_a_map_with_nothing_known_gives_no_footholds_and_says_so(seg):
    r = seg.segment(np.full((100, 100), np.nan), RES, ORIGIN)
    assert r.footholds == [] and r.status == "no data"
    assert seg.segment(np.zeros((0, 0)), RES, ORIGIN).footholds == []
