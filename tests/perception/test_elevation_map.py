"""Elevation map (Section VII-B): Kalman height update, drift correction, moving grid, depth
back-projection, leg cropping and bad frames."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from processes.perception import (
    CropBox,
    ElevationMap,
    ElevationMapParams,
    backproject,
    crop_boxes,
    quat_to_rotmat,
    transform_points,
)
from runtime.errors import ConfigError
from runtime.params import load

REPO = Path(__file__).resolve().parents[2]
PARAMS = ElevationMapParams(length_m=1.0, resolution_m=0.05)   # 20 x 20 cells


def _cell_point(m: ElevationMap, row: int, col: int, z: float) -> np.ndarray:
    return np.array([m.origin[0] + col * m.resolution, m.origin[1] + row * m.resolution, z])


def test_grid_size_and_cell_centres_follow_the_message_convention() -> None:
    m = ElevationMap(PARAMS)
    assert m.shape == (20, 20)
    x, y = m.cell_centers()
    assert x[3, 7] == pytest.approx(m.origin[0] + 7 * 0.05)
    assert y[3, 7] == pytest.approx(m.origin[1] + 3 * 0.05)
    assert np.allclose(m.center, 0.0)
    rows, cols, inside = m.world_to_index(np.array([[x[3, 7] + 0.02, y[3, 7] - 0.02]]))
    assert (rows[0], cols[0], inside[0]) == (3, 7, True)


def test_kalman_update_is_the_inverse_variance_weighted_mean() -> None:
    m = ElevationMap(PARAMS)
    p = _cell_point(m, 5, 5, 0.10)
    assert m.integrate_points(p[None], 0.0004) == 1
    assert m.elevation[5, 5] == pytest.approx(0.10) and m.variance[5, 5] == pytest.approx(4e-4)
    m.integrate_points(_cell_point(m, 5, 5, 0.12)[None], 0.0001)
    # h = (h1/v1 + h2/v2) / (1/v1 + 1/v2), v = 1 / (1/v1 + 1/v2)
    assert m.elevation[5, 5] == pytest.approx((0.10 / 4e-4 + 0.12 / 1e-4) / (1 / 4e-4 + 1e4))
    assert m.variance[5, 5] == pytest.approx(1.0 / (1 / 4e-4 + 1e4))
    assert np.isnan(m.elevation[5, 6])            # other cells untouched


def test_many_points_in_one_frame_equal_sequential_kalman_updates() -> None:
    rng = np.random.default_rng(0)
    batch, seq = ElevationMap(PARAMS), ElevationMap(PARAMS)
    cells = rng.integers(0, 20, size=(300, 2))
    z = 0.2 + rng.normal(0, 0.003, 300)
    var = rng.uniform(1e-5, 4e-5, 300)
    pts = np.column_stack([_cell_point(batch, r, c, 0.0)[:2] for r, c in cells])
    pts = np.column_stack((pts.T, z))
    seq.integrate_points(pts[:1], var[:1])       # seed so both start from the same prior
    batch.integrate_points(pts[:1], var[:1])
    batch.integrate_points(pts[1:], var[1:])
    for k in range(1, 300):                      # the reference: one point at a time
        seq.integrate_points(pts[k:k + 1], var[k:k + 1])
    ok = np.isfinite(seq.elevation)
    assert np.array_equal(ok, np.isfinite(batch.elevation))
    assert np.allclose(batch.elevation[ok], seq.elevation[ok], atol=1e-9)
    assert np.allclose(batch.variance[ok], seq.variance[ok], rtol=1e-9)


def test_outlier_is_not_fused_and_inflates_the_variance() -> None:
    params = ElevationMapParams(length_m=1.0, resolution_m=0.05, multi_height_noise_m2=1e-5,
                                max_variance_m2=1e-3)
    m = ElevationMap(params)
    m.integrate_points(_cell_point(m, 2, 2, 0.0)[None], 1e-6)
    m.integrate_points(_cell_point(m, 2, 2, 0.5)[None], 1e-6)      # 350 sigma away
    assert m.elevation[2, 2] == pytest.approx(0.0)
    assert m.variance[2, 2] == pytest.approx(1e-6 + 1e-5)
    frames = 0
    while not m.elevation[2, 2] > 0.25 and frames < 1000:   # moved obstacle: accepted
        m.integrate_points(_cell_point(m, 2, 2, 0.5)[None], 1e-6)
        frames += 1
    assert m.elevation[2, 2] == pytest.approx(0.5)
    assert 50 < frames < 200                         # after ~ (1e-3 / 1e-5) rejected frames


def test_an_obstacle_on_known_ground_is_in_the_map_one_frame_later() -> None:
    """With ``obstacle_variance_m2`` a rejected measurement above a cell opens the cell up:
    a cube dropped on mapped ground is in the map at the second frame that sees it; a point
    below the cell (seen past an edge) does not open it; and one lone outlier above leaves
    the ground in place, since the next measurement is the ground's."""
    params = ElevationMapParams(length_m=1.0, resolution_m=0.05, obstacle_variance_m2=0.01)
    m = ElevationMap(params)
    for _ in range(20):
        m.integrate_points(_cell_point(m, 2, 2, 0.0)[None], 1e-5)
        m.integrate_points(_cell_point(m, 4, 4, 0.0)[None], 1e-5)
    m.integrate_points(_cell_point(m, 2, 2, 0.15)[None], 1e-5)   # the cube, first frame
    assert m.elevation[2, 2] == pytest.approx(0.0, abs=1e-6)
    m.integrate_points(_cell_point(m, 2, 2, 0.15)[None], 1e-5)   # second frame
    assert m.elevation[2, 2] == pytest.approx(0.15, abs=1e-3)
    v = m.variance[4, 4]
    m.integrate_points(_cell_point(m, 4, 4, -0.2)[None], 1e-5)   # below: no opening up
    assert m.variance[4, 4] < v + 1e-5
    m.integrate_points(_cell_point(m, 4, 4, 0.3)[None], 1e-5)    # a lone outlier above
    m.integrate_points(_cell_point(m, 4, 4, 0.0)[None], 1e-5)    # ... then the ground again
    assert m.elevation[4, 4] == pytest.approx(0.0, abs=1e-3)


def test_drift_correction_matches_the_map_to_the_stance_foot_with_a_4x4_median() -> None:
    m = ElevationMap(PARAMS)
    x, y = m.cell_centers()
    pts = np.column_stack((x.ravel(), y.ravel(), np.full(x.size, 0.30)))
    m.integrate_points(pts, 1e-6)
    foot = _cell_point(m, 10, 10, 0.25)
    foot[:2] -= 0.5 * m.resolution               # the corner shared by cells 9..10: 4x4 = 8..11
    m.elevation[9, 9] = 2.0                      # outliers in the patch do not move the median
    m.elevation[10, 11] = -1.0
    m.elevation[0, 0] = 5.0                      # outside the patch: ignored
    offset = m.apply_drift_correction(foot)
    assert offset == pytest.approx(-0.05)
    assert m.elevation[12, 3] == pytest.approx(0.25)
    assert m.elevation[0, 0] == pytest.approx(4.95)    # the whole map moves
    assert np.median(m.elevation[8:12, 8:12]) == pytest.approx(0.25)


def test_drift_correction_without_map_data_under_the_foot_does_nothing() -> None:
    m = ElevationMap(PARAMS)
    assert m.apply_drift_correction([0.0, 0.0, 0.3]) is None
    assert m.apply_drift_correction([50.0, 0.0, 0.3]) is None     # off the map
    assert m.apply_drift_correction([np.nan, 0.0, 0.3]) is None   # no estimate


def test_recenter_moves_the_grid_in_whole_cells_and_keeps_world_heights() -> None:
    m = ElevationMap(PARAMS)
    p = _cell_point(m, 10, 12, 0.42)
    m.integrate_points(p[None], 1e-6)
    shift = m.recenter([0.16, -0.11])            # 3.2 and -2.2 cells: snaps to 3, -2
    assert shift == (-2, 3)
    assert np.allclose(m.center, [0.15, -0.10])
    rows, cols, inside = m.world_to_index(p[None, :2])
    assert inside[0] and m.elevation[rows[0], cols[0]] == pytest.approx(0.42)
    assert np.count_nonzero(np.isfinite(m.elevation)) == 1
    m.recenter([5.0, 5.0])                        # a jump beyond the map forgets everything
    assert not np.isfinite(m.elevation).any()


def test_backprojection_and_camera_pose_reproduce_the_ground_plane() -> None:
    # a camera 1 m above the ground looking straight down: optical z = world -z
    h, w, f = 48, 64, 50.0
    depth = np.full((h, w), 1.0)
    depth[0, 0] = 0.0                            # no-data pixel
    depth[1, 1] = np.nan
    pts_c = backproject(depth, f, f, (w - 1) / 2, (h - 1) / 2)
    assert pts_c.shape == (h * w - 2, 3)
    quat = np.array([0.0, 1.0, 0.0, 0.0])       # 180 deg about x: z down, y flipped
    pts_w = transform_points(pts_c, [0.1, 0.0, 1.0], quat)
    assert np.allclose(pts_w[:, 2], 0.0)
    assert pts_w[:, 0].min() == pytest.approx(0.1 - (w - 1) / 2 / f)
    m = ElevationMap(PARAMS)
    status = m.update_from_depth(depth, f, f, (w - 1) / 2, (h - 1) / 2, [0.1, 0.0, 1.0], quat)
    assert status == "ok"
    assert np.nanmax(np.abs(m.elevation)) < 1e-9 and np.isfinite(m.elevation).sum() > 100


def test_quaternion_is_wxyz() -> None:
    r = quat_to_rotmat([np.cos(np.pi / 4), 0.0, 0.0, np.sin(np.pi / 4)])   # 90 deg about z
    assert np.allclose(r @ [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])


def test_points_inside_leg_boxes_are_cropped() -> None:
    pts = np.array([[0.0, 0.0, 0.5], [0.0, 0.0, 0.0], [0.3, 0.0, 0.5]])
    box = CropBox(np.array([0.0, 0.0, 0.5]), quat_to_rotmat([np.cos(0.3), 0, np.sin(0.3), 0]),
                  np.array([0.05, 0.05, 0.3]))
    assert crop_boxes(pts, [box]).tolist() == [False, True, True]
    m = ElevationMap(PARAMS)
    depth = np.full((10, 10), 1.0)
    everything = CropBox(np.zeros(3), np.eye(3), np.full(3, 10.0))
    status = m.update_from_depth(depth, 10, 10, 5, 5, [0, 0, 1], [0, 1, 0, 0], [everything])
    assert status == "all points cropped" and not np.isfinite(m.elevation).any()


@pytest.mark.parametrize("depth", [np.zeros((30, 40)), np.full((30, 40), np.nan),
                                   np.full((30, 40), 50.0), np.empty((0, 0))])
def test_frame_without_valid_depth_leaves_the_map_and_says_why(depth: np.ndarray) -> None:
    m = ElevationMap(PARAMS)
    m.integrate_points(np.array([[0.0, 0.0, 0.1]]), 1e-6)
    before = m.elevation.copy()
    status = m.update_from_depth(depth, 30, 30, 20, 15, [0, 0, 1], [0, 1, 0, 0])
    assert status == "no valid depth"
    assert np.array_equal(before, m.elevation, equal_nan=True)


def test_points_outside_the_map_are_ignored() -> None:
    m = ElevationMap(PARAMS)
    assert m.integrate_points(np.array([[9.0, 9.0, 1.0], [np.nan, 0, 0]]), 1e-4) == 0
    depth = np.full((10, 10), 1.0)
    status = m.update_from_depth(depth, 10, 10, 5, 5, [9, 9, 1], [0, 1, 0, 0])
    assert status == "no points in map"


def test_parameters_load_from_both_variants_and_reject_bad_values(tmp_path: Path) -> None:
    path = REPO / "hw_config" / "gains" / "elevation_map.yaml"
    sim = load(ElevationMapParams, path)
    hw = load(ElevationMapParams, path, "hardware")
    assert (sim.length_m, sim.resolution_m, sim.cells) == (2.5, 0.025, 100)   # Table VIII
    assert (hw.length_m, hw.resolution_m, hw.cells) == (3.0, 0.03, 100)
    assert sim.drift_patch_px == 4
    bad = tmp_path / "em.yaml"
    bad.write_text("variants:\n  s:\n    resolution_m: -0.1\n")
    with pytest.raises(ConfigError, match=r"em.yaml: variants.s.resolution_m: out of range"):
        load(ElevationMapParams, bad, "s")
    bad.write_text("min_depth_m: 2.0\nmax_depth_m: 1.0\n")
    with pytest.raises(ConfigError, match=r"em.yaml: max_depth_m: must exceed min_depth_m"):
        load(ElevationMapParams, bad)


def test_a_riser_seen_edge_on_does_not_drag_the_edge_cell_down() -> None:
    m = ElevationMap(PARAMS)
    top = np.tile(_cell_point(m, 4, 4, 0.30), (5, 1))
    riser = np.tile(_cell_point(m, 4, 4, 0.0), (20, 1))
    riser[:, 2] = np.linspace(0.0, 0.28, 20)       # a vertical face inside the same cell
    m.integrate_points(np.vstack((top, riser)), 1e-6)
    assert m.elevation[4, 4] == pytest.approx(0.30, abs=1e-3)


@pytest.mark.parametrize("intrinsics, pose, status", [
    ((0.0, 30.0, 20.0, 15.0), ([0, 0, 1], [0, 1, 0, 0]), "bad intrinsics"),
    ((30.0, np.nan, 20.0, 15.0), ([0, 0, 1], [0, 1, 0, 0]), "bad intrinsics"),
    ((30.0, 30.0, 20.0, 15.0), ([0, 0, 1], [0, 0, 0, 0]), "bad camera pose"),
    ((30.0, 30.0, 20.0, 15.0), ([0, np.inf, 1], [0, 1, 0, 0]), "bad camera pose"),
])
def test_bad_camera_data_leaves_the_map_and_says_why(intrinsics: tuple[float, ...],
                                                     pose: tuple[list[float], list[float]],
                                                     status: str) -> None:
    m = ElevationMap(PARAMS)
    with np.errstate(all="raise"):
        assert m.update_from_depth(np.ones((30, 40)), *intrinsics, *pose) == status
    assert not np.isfinite(m.elevation).any()


def test_initial_submap_fills_unknown_cells_under_the_feet_until_the_camera_sees_them() -> None:
    params = ElevationMapParams(length_m=2.0, resolution_m=0.05, init_submap_back_m=0.5,
                                init_submap_front_m=0.2, init_submap_half_y_m=0.3)
    m = ElevationMap(params)
    known = _cell_point(m, 20, 20, 0.7)                 # a cell already measured keeps its value
    m.integrate_points(known[None], 1e-6)
    filled = m.initialize_submap(known[:2], 0.1)
    assert filled > 0
    x, y = m.cell_centers()
    ahead = x - known[0]
    inside = (ahead >= -0.5) & (ahead <= 0.2) & (np.abs(y - known[1]) <= 0.3)
    assert np.count_nonzero(inside) == filled + 1
    assert m.elevation[20, 20] == pytest.approx(0.7)
    assert np.allclose(m.elevation[inside & ~np.isclose(m.elevation, 0.7)], 0.1)
    assert np.isnan(m.elevation[~inside]).all()         # nothing past the box (ahead: 0.2 m)
    # the first measurement of a prior cell replaces it, even 0.5 m away (a pit's floor)
    pit = _cell_point(m, 20, 16, -0.4)
    assert m.elevation[20, 16] == pytest.approx(0.1)
    m.integrate_points(pit[None], 1e-6)
    assert m.elevation[20, 16] == pytest.approx(-0.4)
    m.integrate_points(_cell_point(m, 20, 16, 0.1)[None], 1e-6)   # then it fuses as usual
    assert m.elevation[20, 16] == pytest.approx(-0.4)


def test_initial_submap_is_off_by_default() -> None:
    m = ElevationMap(ElevationMapParams(length_m=1.0, resolution_m=0.05))
    assert m.initialize_submap([0.0, 0.0], 0.0) == 0
    assert np.isnan(m.elevation).all()
