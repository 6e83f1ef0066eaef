"""The one foothold type (runtime.geometry) and the codecs of foothold_set_t and elevation_map_t
(runtime.codecs): half-spaces, containment and heights on a plane; degenerate polygons refused
with a clear error; footholds and maps through real LCM messages and back."""

from __future__ import annotations

import numpy as np
import pytest

from lcmtypes import elevation_map_t, foothold_set_t, foothold_t
from runtime.codecs import (
    FOOTHOLDS_EMPTY,
    FOOTHOLDS_OK,
    FOOTHOLDS_PREVIOUS,
    MAP_STALE,
    elevation_map_from_msg,
    elevation_map_problem,
    elevation_map_to_msg,
    foothold_set_problem,
    footholds_from_msg,
    footholds_to_msg,
)
from runtime.geometry import Foothold, signed_area
from runtime.validate import InputCheck

SQUARE = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
TILT = np.array([0.1, -0.05, 1.0]) / np.linalg.norm([0.1, -0.05, 1.0])


def _through_lcm(msg: foothold_set_t) -> foothold_set_t:
    return foothold_set_t.decode(msg.encode())


def test_from_polygon_contains_interior_points_on_its_plane() -> None:
    fh = Foothold.from_polygon(SQUARE[[2, 0, 3, 1]], normal=(0.1, 0.0, 1.0), offset=0.3)
    p = np.array([0.5, 0.5, 0.0])
    p[2] = fh.height_at(p[:2])
    assert np.isclose(p[2], 0.3 - 0.05)
    assert fh.contains(p)
    assert not fh.contains(p + np.array([0.0, 0.0, 0.01]))  # off the plane
    assert not fh.contains(np.array([1.2, 0.5, fh.height_at([1.2, 0.5])]))
    assert np.allclose(np.linalg.norm(fh.A, axis=1), 1.0)  # (20) needs unit rows
    assert np.isclose(np.linalg.norm(fh.normal), 1.0) and fh.normal[2] > 0
    assert signed_area(fh.vertices_xy) > 0 and np.isclose(fh.area_m2, 1.0)  # sorted CCW


def test_general_halfspaces_project_to_the_right_polygon() -> None:
    """A tilted wall (non-zero z in A) is eliminated through the plane correctly."""
    # plane z = 0.5 x; the wall x + z <= 1.5 becomes 1.5 x <= 1.5 on the plane
    a = np.array([[1.0, 0, 1.0], [-1.0, 0, 0], [0, 1.0, 0], [0, -1.0, 0]])
    b = np.array([1.5, 0.0, 1.0, 0.0])
    fh = Foothold(a, b, normal=np.array([-0.5, 0.0, 1.0]), offset=0.0)
    v = fh.vertices_xy
    assert np.isclose(v[:, 0].max(), 1.0) and np.isclose(v[:, 0].min(), 0.0)
    assert len(v) == 4
    assert fh.contains_xy(0.99, 0.5) and not fh.contains_xy(1.01, 0.5)


def test_from_ccw_keeps_the_corners_and_plane_and_walls_each_edge() -> None:
    poly = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 2.0], [0.0, 1.0]])
    fh = Foothold.from_ccw(poly, TILT, 0.2)
    assert fh.normal.tobytes() == TILT.tobytes() and fh.offset == 0.2  # exactly as given
    assert np.array_equal(fh.vertices_xy, poly)
    assert fh.A.shape == (4, 3) and np.all(fh.A[:, 2] == 0.0)
    assert np.allclose(np.linalg.norm(fh.A, axis=1), 1.0)
    # row k: the outward normal of the edge from corner k to k + 1, through corner k
    edge = np.roll(poly, -1, axis=0) - poly
    assert np.allclose(np.einsum("ij,ij->i", fh.A[:, :2], edge), 0.0)
    assert np.allclose(np.einsum("ij,ij->i", fh.A[:, :2], poly), fh.b)
    assert np.all(fh.A[:, :2] @ poly.mean(axis=0) < fh.b)  # the inside is behind every wall
    # the corners lie on the plane, and a point above the polygon is inside at any height
    assert np.allclose(fh.vertices @ TILT, 0.2)
    assert np.all(fh.A @ np.array([0.5, 0.5, 7.0]) <= fh.b)
    assert np.isclose(fh.area_m2, 1.5)
    # containment of the projection: edges and corners inside, a hair beyond them outside
    assert fh.contains_xy(0.0, 0.0) and fh.contains_xy(0.5, 1.5) and fh.contains_xy(1.0, 1.0)
    assert not fh.contains_xy(0.5, 1.5 + 1e-9) and not fh.contains_xy(-1e-9, 0.5)
    p = np.array([0.4, 0.6, 0.0])
    p[2] = fh.height_at(p[:2])
    assert fh.contains(p) and np.isclose(TILT @ p, 0.2)


def test_many_from_ccw_gives_what_from_ccw_gives_one_by_one_and_names_a_bad_polygon() -> None:
    polys = [np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 2.0], [0.0, 1.0]]),
             np.array([[2.0, 0.0], [3.0, 0.5], [2.5, 1.0]]), SQUARE + 5.0]
    normals = np.array([TILT, [0.0, 0.0, 1.0], TILT])
    offsets = [0.2, -0.1, 0.0]
    bounds = np.cumsum([0] + [len(v) for v in polys])
    many = Foothold.many_from_ccw(np.concatenate(polys), bounds, normals, offsets)
    assert len(many) == 3
    for f, v, n, d in zip(many, polys, normals, offsets, strict=True):
        one = Foothold.from_ccw(v, n, d)
        for name in ("A", "b", "normal", "vertices_xy"):
            assert np.array_equal(getattr(f, name), getattr(one, name))
            assert not getattr(f, name).flags.writeable
        assert f.offset == one.offset and np.array_equal(f.halfspaces_xy[0], one.halfspaces_xy[0])
    assert Foothold.many_from_ccw(np.zeros((0, 2)), [0], np.zeros((0, 3)), []) == []
    polys[1] = polys[1][::-1]  # clockwise
    with pytest.raises(ValueError, match=r"counter-clockwise.*\(polygon 1 of 3\)"):
        Foothold.many_from_ccw(np.concatenate(polys), bounds, normals, offsets)


@pytest.mark.parametrize(("make", "message"), [
    (lambda: Foothold.from_polygon(np.array([[0.0, 0.0], [1.0, 1.0], [1.0, 1.0]])),
     "at least 3 distinct corners"),
    (lambda: Foothold.from_ccw(np.array([[0.0, 0.0], [1.0, 1.0], [2.0, 2.0]]), (0, 0, 1), 0.0),
     "must enclose an area"),
    (lambda: Foothold.from_ccw(SQUARE[::-1], (0, 0, 1), 0.0), "counter-clockwise"),
    (lambda: Foothold.from_ccw(SQUARE[[0, 1, 1, 2, 3]], (0, 0, 1), 0.0), "repeated corner"),
    (lambda: Foothold.from_ccw(SQUARE[:2], (0, 0, 1), 0.0), "k >= 3"),
    (lambda: Foothold.from_ccw(SQUARE, (0, 0, 2.0), 0.0), "unit normal"),
    (lambda: Foothold(np.eye(3), np.ones(3), normal=np.zeros(3), offset=0.0), "normal"),
    (lambda: Foothold(np.eye(3)[:2], np.ones(2), (0, 0, 1), 0.0), "k >= 3 half-space rows"),
    (lambda: Foothold(np.diag([1.0, 1.0, 0.0]), np.ones(3), (0, 0, 1), 0.0), "non-zero"),
    (lambda: Foothold(np.eye(3), np.ones(3), (0, 0, 1), float("nan")), "offset must be finite"),
])
def test_a_degenerate_polygon_is_refused_with_a_clear_error(make, message) -> None:
    with pytest.raises(ValueError, match=message):
        make()


def test_erosion_leaves_the_centres_of_a_rectangle_that_fits() -> None:
    fh = Foothold.from_ccw(np.array([[0.0, 0.0], [0.4, 0.0], [0.4, 0.3], [0.0, 0.3]]),
                           (0.0, 0.0, 1.0), 0.1)
    small = fh.eroded(0.1, 0.02)
    assert small is not None
    np.testing.assert_allclose(small.vertices_xy.min(axis=0), [0.1, 0.02])
    np.testing.assert_allclose(small.vertices_xy.max(axis=0), [0.3, 0.28])
    np.testing.assert_allclose(small.vertices[:, 2], 0.1)
    assert fh.eroded(0.2, 0.0) is None  # exactly as long as the face: no area left
    tilted_wall = Foothold(np.array([[1.0, 0, 1.0], [-1.0, 0, 0], [0, 1.0, 0], [0, -1.0, 0]]),
                           np.array([1.5, 0.0, 1.0, 0.0]), (0, 0, 1), 0.0)
    with pytest.raises(ValueError, match="vertical walls"):
        tilted_wall.eroded(0.1, 0.1)


def test_erosion_for_a_turned_foot_shrinks_a_turned_rectangle_along_its_own_axes() -> None:
    yaw = 0.5
    u, n = np.array([np.cos(yaw), np.sin(yaw)]), np.array([-np.sin(yaw), np.cos(yaw)])
    corners = np.array([s * 0.3 * u + t * 0.15 * n for s, t in ((-1, -1), (1, -1), (1, 1),
                                                                 (-1, 1))])
    fh = Foothold.from_ccw(corners, (0.0, 0.0, 1.0), 0.0)
    small = fh.eroded(0.1, 0.02, yaw)
    assert small is not None
    local = small.vertices_xy @ np.stack([u, n]).T  # in the rectangle's own axes
    np.testing.assert_allclose(np.abs(local), [[0.2, 0.13]] * 4, atol=1e-12)
    facing_x = fh.eroded(0.1, 0.02)  # a foot facing +x needs more room across the turned face
    assert facing_x is not None
    assert signed_area(facing_x.vertices_xy) < signed_area(small.vertices_xy)


def test_a_foothold_set_round_trips_through_its_message() -> None:
    level = Foothold.from_ccw(np.array([[0.0, -0.5], [1.0, -0.5], [1.0, 0.5], [0.0, 0.5]]),
                              (0.0, 0.0, 1.0), 0.15)
    tilted = Foothold.from_ccw(np.array([[1.2, 0.0], [1.7, 0.1], [1.5, 0.6]]), TILT, 0.3)
    sorted_ = Foothold.from_polygon(np.array([[2.0, 0.0], [2.0, 0.4], [2.4, 0.0], [2.4, 0.4]]),
                                    (0.0, 0.1, 1.0), 0.05)
    sent = [level, tilted, sorted_]
    msg = _through_lcm(footholds_to_msg(sent, utime=123, map_seq=7, status_text="ok"))
    assert (msg.header.utime, msg.map_seq, msg.status, msg.status_text) == (123, 7,
                                                                           FOOTHOLDS_OK, "ok")
    assert msg.num_footholds == 3 and foothold_set_problem(msg) is None
    assert InputCheck(foothold_set_t)(msg) is None  # what the runners admit
    got = footholds_from_msg(msg)
    assert len(got) == 3
    for a, b in zip(sent, got, strict=True):
        np.testing.assert_allclose(b.A, a.A, rtol=0, atol=1e-15)
        np.testing.assert_allclose(b.b, a.b, rtol=0, atol=1e-15)
        np.testing.assert_allclose(b.normal, a.normal, rtol=0, atol=1e-15)
        assert b.offset == pytest.approx(a.offset, abs=1e-15)
        np.testing.assert_allclose(b.vertices, a.vertices, atol=1e-12)
        np.testing.assert_allclose(msg.footholds[sent.index(a)].vertices, a.vertices, atol=0)
    # a level box top needs no rescaling: its half-spaces and plane come back to the bit
    back = got[0]
    for x, y in ((back.A, level.A), (back.b, level.b), (back.normal, level.normal)):
        assert x.tobytes() == y.tobytes()
    assert back.offset == level.offset


def test_foothold_set_status_and_a_malformed_polygon_costs_only_itself() -> None:
    assert footholds_to_msg([]).status == FOOTHOLDS_EMPTY
    square = Foothold.from_ccw(SQUARE, (0.0, 0.0, 1.0), 0.0)
    assert footholds_to_msg([square], previous=True).status == FOOTHOLDS_PREVIOUS
    msg = footholds_to_msg([square, square])
    bad = foothold_t()  # a zero row: no half-space
    bad.normal, bad.offset = [0.0, 0.0, 1.0], 0.0
    bad.num_halfspaces, bad.A, bad.b = 3, [[1.0, 0, 0], [0, 0, 0], [0, 1.0, 0]], [1.0, 1.0, 1.0]
    msg.footholds.insert(1, bad)
    msg.num_footholds = 3
    assert len(footholds_from_msg(_through_lcm(msg))) == 2
    bad.num_halfspaces, bad.A, bad.b = 2, [[1.0, 0, 0], [0, 1.0, 0]], [1.0, 1.0]
    assert foothold_set_problem(msg) == "foothold 1 with 2 half-space rows and 2 offsets"
    bad.num_halfspaces, bad.A, bad.b = 3, [[1.0, 0, 0], [0, 1.0, 0], [-1, -1, 0]], [1, 1, 1]
    bad.normal = [0.0, 0.0, 0.1]
    assert foothold_set_problem(msg) == "foothold 1 with a normal of length < 0.5"


def test_an_elevation_map_round_trips_through_its_message() -> None:
    rng = np.random.default_rng(3)
    elevation = rng.normal(0.0, 0.1, (6, 9)).astype(np.float32)
    elevation[2, 3] = np.nan
    layers = {"elevation": elevation, "variance": np.full((6, 9), 1e-4, np.float32),
              "lowest": elevation.astype(np.float64) - 0.01}  # float64 goes out as float32
    msg = elevation_map_t.decode(elevation_map_to_msg(
        layers, 0.025, np.array([1.5, -0.2]), utime=42, status=MAP_STALE,
        status_text="not fused").encode())
    assert (msg.rows, msg.cols, msg.resolution, list(msg.origin)) == (6, 9, 0.025, [1.5, -0.2])
    assert (msg.header.utime, msg.status, msg.status_text) == (42, MAP_STALE, "not fused")
    assert list(msg.layer_names) == ["elevation", "variance", "lowest"]  # order kept
    assert elevation_map_problem(msg) is None and InputCheck(elevation_map_t)(msg) is None
    got = elevation_map_from_msg(msg)
    assert isinstance(got, dict) and list(got) == list(layers)
    for name, grid in layers.items():
        assert got[name].dtype == np.float32 and got[name].shape == (6, 9)
        np.testing.assert_array_equal(got[name], grid.astype(np.float32))


def test_an_inconsistent_elevation_map_is_refused_with_its_reason() -> None:
    with pytest.raises(ValueError, match="one shape"):
        elevation_map_to_msg({"a": np.zeros((2, 3)), "b": np.zeros((3, 2))}, 0.1, (0.0, 0.0))
    msg = elevation_map_to_msg({"elevation": np.zeros((4, 5))}, 0.1, (0.0, 0.0))
    msg.data = msg.data[:-4]
    why = "an elevation map of 76 data bytes where 4 x 5 cells x 1 layers of float32 make 80"
    assert elevation_map_from_msg(msg) == why == elevation_map_problem(msg)
    assert InputCheck(elevation_map_t)(msg) == why  # the runners refuse it for the same reason
    msg = elevation_map_to_msg({"elevation": np.zeros((4, 5))}, 0.0, (0.0, 0.0))
    assert elevation_map_from_msg(msg) == "an elevation map with resolution 0.0"
