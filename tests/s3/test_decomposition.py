"""Convex decomposition (Section VI-B): ACD, whittling (Algorithm 1) and MakeCut (Eq. (27),
Algorithm 2)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from processes.s3.decomposition import (
    approximate_convex_decomposition,
    clip_halfplane,
    convex_decomposition,
    convex_hull,
    depth_inside,
    make_cut,
    whittle,
)
from runtime.geometry import signed_area

RES = 0.025


def _is_convex_ccw(poly: np.ndarray, tol: float = 1e-9) -> bool:
    e = np.roll(poly, -1, axis=0) - poly
    e_next = np.roll(e, -1, axis=0)
    cross = e[:, 0] * e_next[:, 1] - e[:, 1] * e_next[:, 0]
    return bool(np.all(cross >= -tol * np.abs(e).max() ** 2)) and signed_area(poly) > 0


def _cells_inside(poly: np.ndarray, shape: tuple[int, int], margin: float) -> np.ndarray:
    """Mask of cells whose centre is at least `margin` px inside the convex polygon."""
    r, c = np.indices(shape)
    pts = np.column_stack((c.ravel(), r.ravel())).astype(float)
    d, _ = depth_inside(poly, pts)
    return (d >= margin).reshape(shape)


def _polygon_cost(vertices: np.ndarray, vi: np.ndarray, a: np.ndarray) -> float:
    m = np.maximum((vi - vertices) @ a, 0.0)
    return float(m @ m)


def _l_shape() -> np.ndarray:
    mask = np.zeros((80, 80), np.uint8)
    mask[5:75, 5:25] = 1
    mask[55:75, 5:75] = 1
    return mask


def test_l_shape_deeper_than_the_concavity_limit_is_cut_in_two() -> None:
    pieces, cuts = approximate_convex_decomposition(_l_shape(), RES, 0.25, 0.05)
    assert cuts == 1 and len(pieces) == 2
    # a d-approximately convex shape is left alone: with d = 1 m the L stays whole
    pieces, cuts = approximate_convex_decomposition(_l_shape(), RES, 1.0, 0.05)
    assert cuts == 0 and len(pieces) == 1


def test_a_hole_is_cut_and_no_polygon_covers_it() -> None:
    mask = np.zeros((80, 80), np.uint8)
    mask[5:75, 5:75] = 1
    mask[30:45, 35:50] = 0
    polys = convex_decomposition(mask, RES, 0.25, 0.05, 0.02)
    assert len(polys) >= 2
    covered = np.zeros(mask.shape, bool)
    for p in polys:
        inside = _cells_inside(p, mask.shape, 0.5)
        assert not np.any(inside & (mask == 0))
        covered |= inside
    assert covered.sum() > 0.6 * mask.sum()


def test_small_regions_are_dropped() -> None:
    mask = np.zeros((60, 60), np.uint8)
    mask[5:13, 5:13] = 1               # 0.04 m^2 < 0.05 m^2
    mask[20:55, 20:55] = 1
    polys = convex_decomposition(mask, RES, 0.25, 0.05, 0.02)
    assert len(polys) == 1
    assert polys[0][:, 0].min() >= 19.5


@st.composite
def _region_masks(draw: st.DrawFn) -> np.ndarray:
    """Unions of rectangles and discs minus a few holes: non-convex regions with holes."""
    mask = np.zeros((70, 70), np.uint8)
    for _ in range(draw(st.integers(1, 4))):
        x, y = draw(st.integers(0, 55)), draw(st.integers(0, 55))
        w, h = draw(st.integers(8, 50)), draw(st.integers(8, 50))
        mask[y:y + h, x:x + w] = 1
    for _ in range(draw(st.integers(0, 2))):
        cx, cy, r = draw(st.integers(5, 65)), draw(st.integers(5, 65)), draw(st.integers(3, 12))
        cv2.circle(mask, (cx, cy), r, 1, -1)
    for _ in range(draw(st.integers(0, 3))):
        cx, cy, r = draw(st.integers(5, 65)), draw(st.integers(5, 65)), draw(st.integers(2, 6))
        cv2.circle(mask, (cx, cy), r, 0, -1)
    return mask


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(_region_masks())
def test_whittled_polygons_are_convex_and_inside_the_original_region(mask: np.ndarray) -> None:
    polys = convex_decomposition(mask, RES, 0.25, 0.05, 0.02)
    for p in polys:
        assert _is_convex_ccw(p)
        # cells whose centre is inside the polygon are safe cells; half a cell of slack
        # covers the contour (through cell centres) and Douglas-Peucker tolerance
        inside = _cells_inside(p, mask.shape, 0.5)
        assert not np.any(inside & (mask == 0))
        assert p[:, 0].min() >= 0 and p[:, 1].min() >= 0
        assert p[:, 0].max() <= mask.shape[1] - 1 and p[:, 1].max() <= mask.shape[0] - 1
    # polygons do not overlap (ACD pieces are disjoint, whittling only shrinks them)
    for i in range(len(polys)):
        for j in range(i + 1, len(polys)):
            a = _cells_inside(polys[i], mask.shape, 0.5)
            b = _cells_inside(polys[j], mask.shape, 0.5)
            assert not np.any(a & b)


def test_whittling_a_notched_square_removes_the_notch_and_keeps_most_area() -> None:
    square_notch = np.array([[0, 0], [10, 0], [10, 10], [6, 10], [5, 7], [4, 10], [0, 10]],
                            float)
    p = whittle(square_notch, tol=1e-6)
    assert _is_convex_ccw(p)
    assert depth_inside(p, np.array([[5.0, 7.0]]))[0][0] <= 1e-6   # the notch is not inside
    assert signed_area(p) == pytest.approx(70.0, rel=0.05)            # cut at y = 7
    # an already convex polygon is returned unchanged (its hull)
    hexagon = np.array([[np.cos(t), np.sin(t)] for t in np.linspace(0, 2 * np.pi, 7)[:-1]])
    assert signed_area(whittle(hexagon)) == pytest.approx(signed_area(convex_hull(hexagon)))


def test_make_cut_is_a_minimiser_of_eq_27_on_the_unit_circle() -> None:
    rng = np.random.default_rng(3)
    for _ in range(20):
        v = rng.normal(size=(12, 2))
        vi = v[0] * 0.3
        a0 = rng.normal(size=2)
        a = make_cut(v, vi, a0, eps=1e-9, max_iters=200)
        assert np.linalg.norm(a) == pytest.approx(1.0)
        f = _polygon_cost(v, vi, a)
        assert f <= _polygon_cost(v, vi, a0 / np.linalg.norm(a0)) + 1e-12
        for da in (-1e-3, 1e-3):   # a local minimum along the circle
            rot = np.array([[np.cos(da), -np.sin(da)], [np.sin(da), np.cos(da)]])
            assert f <= _polygon_cost(v, vi, rot @ a) + 1e-9
    # a convex cost: the solver finds the global minimum of a brute-force angle sweep
    v = np.array([[0.0, 0.0], [4.0, 0.0], [4.0, 4.0], [0.0, 4.0], [2.0, 3.0]])
    ang = np.linspace(0, 2 * np.pi, 36000, endpoint=False)
    costs = [_polygon_cost(v, v[4], np.array([np.cos(t), np.sin(t)])) for t in ang]
    a = make_cut(v, v[4], np.array([0.0, -1.0]), eps=1e-10, max_iters=500)
    assert _polygon_cost(v, v[4], a) == pytest.approx(min(costs), abs=1e-3)


def test_clip_halfplane_keeps_the_side_a_dot_x_ge_c() -> None:
    square = np.array([[0, 0], [2, 0], [2, 2], [0, 2]], float)
    half = clip_halfplane(square, np.array([1.0, 0.0]), 1.0)
    assert signed_area(half) == pytest.approx(2.0)
    assert half[:, 0].min() == pytest.approx(1.0)
    assert len(clip_halfplane(square, np.array([1.0, 0.0]), 5.0)) == 0
