"""The plane-segmentation baselines of the paper's Section VIII-D (EM_cupy, EM_cupy_NR): flat
ground is one safe plane, a 40 deg slope is not steppable, a step's edge splits two safe
treads, and a component that is not one plane is refined by RANSAC (EM_cupy) or judged whole
by its slope (EM_cupy_NR)."""

from __future__ import annotations

import numpy as np

from tools.segmentation_baselines import segment

RES = 0.025


def _grid(n: int = 60) -> tuple[np.ndarray, np.ndarray]:
    j, i = np.meshgrid(np.arange(n), np.arange(n))
    return j * RES, i * RES


def test_flat_ground_is_one_safe_plane():
    x, _ = _grid()
    for refine in (True, False):
        r = segment(np.zeros_like(x), RES, refine=refine)
        assert r.planes == 1
        assert r.safe_mask[2:-2, 2:-2].all()  # all but the contour's margin


def test_a_steep_slope_is_not_steppable():
    x, _ = _grid()
    z = np.tan(np.radians(40.0)) * x
    for refine in (True, False):
        assert not segment(z, RES, refine=refine).safe_mask.any()


def test_a_step_edge_splits_two_safe_treads():
    x, _ = _grid()
    z = np.where(x < 0.75, 0.0, 0.15)
    r = segment(z, RES, refine=True)
    assert r.planes == 2
    col = r.safe_mask[30]
    assert col[5:25].all() and col[35:55].all() and not col[29:32].any()


def test_a_gentle_fold_is_split_by_ransac_or_kept_whole_without_it():
    """Two 12 deg planes meeting in a ridge: every 3 x 3 window is planar, so the cells form one
    component; it fails EM_cupy's global fit (cells 2 cm off one plane) and RANSAC refines it
    into planes, while EM_cupy_NR judges the component by its one fitted plane (level: safe)."""
    x, _ = _grid()
    z = 0.21 * np.abs(x - 0.75)
    em = segment(z, RES, refine=True, seed=1)
    nr = segment(z, RES, refine=False)
    assert em.ransac_components == 1 and em.planes >= 2
    assert nr.ransac_components == 0 and nr.planes == 1
    assert nr.safe_mask[5:-5, 5:-5].all()
    # RANSAC is seeded: the same seed, the same mask
    again = segment(z, RES, refine=True, seed=1)
    assert (again.safe_mask == em.safe_mask).all()
