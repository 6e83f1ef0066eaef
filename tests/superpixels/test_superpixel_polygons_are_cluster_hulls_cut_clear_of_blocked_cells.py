"""The superpixels' regions stage (processes.superpixels.segmenter._polygons, one numba call for
all clusters) against geometric invariants: each polygon is its cluster's convex hull on the
cluster's plane, unchanged where that hull covers no blocked cell and cut inside it where it
does; no blocked cell's centre inside; the hull of grid points a rounding error off their
lines is the grid's outline."""

from __future__ import annotations

import numpy as np

from processes.s3.decomposition import convex_hull, depth_inside
from processes.superpixels import SuperpixelParams, SuperpixelSegmenter
from processes.superpixels.segmenter import _EDGE_PX, _hull
from runtime.config import HW_CONFIG_DIR
from runtime.geometry import signed_area
from runtime.params import load

RES = 0.025
ORIGIN = np.array([-1.25, -1.25])
P = load(SuperpixelParams, HW_CONFIG_DIR / "gains" / "superpixels.yaml")
#: px: corners within _EDGE_PX of their neighbours' line are dropped (one after another, so a
#: run of them can shrink a hull by a few times that), and OpenCV's hull is of float32 points
#: (an ulp is 8e-6 px at 100 px)
TOL = 3.0 * _EDGE_PX


def test_the_hull_of_grid_points_a_rounding_error_off_their_lines_is_the_grids_outline():
    u, v = np.meshgrid(np.arange(56.0, 69.0), np.arange(86.0, 93.0))
    pts = np.column_stack((u.ravel(), v.ravel()))
    pts += np.random.default_rng(0).choice([-1.0, 0.0, 1.0], pts.shape) * 1.5e-14
    out = np.empty((2 * len(pts) + 1, 2))
    h = _hull(pts, out)
    want = np.array([[56.0, 86.0], [68.0, 86.0], [68.0, 92.0], [56.0, 92.0]])
    assert h == 4  # no corner lost to the jitter, none kept on an edge
    np.testing.assert_allclose(out[:h], want, atol=1e-12)


def _map() -> np.ndarray:
    """A noisy floor with holes, a U-shaped gap, a box and a tilted plateau."""
    x, y = np.meshgrid(ORIGIN[0] + np.arange(100) * RES, ORIGIN[1] + np.arange(100) * RES)
    rng = np.random.default_rng(5)
    e = 0.004 * rng.standard_normal(x.shape)
    e[(np.abs(x) < 0.5) & (np.abs(y + 0.4) < 0.3) & ~((x > -0.2) & (np.abs(y + 0.4) < 0.1))] \
        = np.nan
    for r0, c0 in rng.integers(5, 95, size=(20, 2)):
        e[r0:r0 + rng.integers(1, 4), c0:c0 + rng.integers(1, 4)] = np.nan
    e[70:80, 10:20] = 0.3
    plateau = (x > 0.3) & (y > 0.2)
    e[plateau] = 0.12 + 0.08 * (x[plateau] - 0.3) - 0.05 * (y[plateau] - 0.2)
    return e


def test_each_polygon_is_its_clusters_hull_on_its_plane_cut_only_where_it_covers_blocked_cells():
    e = _map()
    r = SuperpixelSegmenter(P).segment(e, RES, ORIGIN)
    rows, cols = e.shape
    jj, ii = np.meshgrid(np.arange(cols), np.arange(rows))
    cells = np.column_stack((jj.ravel(), ii.ravel())).astype(float)  # px, x = col
    world = np.column_stack((ORIGIN + cells * RES, np.nan_to_num(e.ravel())))
    blocked = cells[r.safe_mask.ravel() == 0]
    cut = whole = 0
    assert len(r.footholds) >= 20
    for f in r.footholds:
        poly = (f.vertices_xy - ORIGIN) / RES
        # its cluster: the label of most cells under it; their centres onto its plane
        under = np.all(depth_inside(poly, cells)[0].reshape(-1, 1) >= -1e-9, axis=1)
        labels = r.labels.ravel()[under]
        k = np.bincount(labels[labels >= 0]).argmax()
        q = world[r.labels.ravel() == k]
        q = q - np.outer(q @ f.normal - f.offset, f.normal)
        hull = convex_hull((q[:, :2] - ORIGIN) / RES)  # OpenCV's (float32), the previous hull
        assert np.all(depth_inside(hull, poly)[0] >= -TOL)  # inside the cluster's hull
        assert np.all(depth_inside(poly, blocked)[0] < -_EDGE_PX)  # no blocked centre in it
        if np.any(depth_inside(hull, blocked)[0] >= -TOL):
            cut += 1
            assert signed_area(poly) < signed_area(hull) - 1e-9
        else:
            whole += 1  # the same polygon: every corner of each on the other's boundary
            assert np.all(np.abs(depth_inside(hull, poly)[0]) < TOL)
            assert np.all(np.abs(depth_inside(poly, hull)[0]) < TOL)
    assert cut >= 3 and whole >= 10
