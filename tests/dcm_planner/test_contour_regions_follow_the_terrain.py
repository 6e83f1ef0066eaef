"""The DCM planner's terrain front end (Xiang et al., Alg. 3) on elevation maps: one convex
region per flat surface at its height, none across a riser, a hull that would span unsafe
ground dropped, and the velocity-adaptive selection."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from processes.dcm_planner.regions import (
    ContourRegions,
    RegionParams,
    extract_regions,
    select_regions,
)
from runtime.config import HW_CONFIG_DIR
from runtime.params import load

RES = 0.025
P = load(RegionParams, HW_CONFIG_DIR / "gains" / "dcm_regions.yaml")


def _grid(nx: int = 120, ny: int = 80) -> tuple[np.ndarray, np.ndarray]:
    xs, ys = np.arange(nx) * RES - 1.0, np.arange(ny) * RES - 1.0
    return np.meshgrid(xs, ys)


def test_every_tread_is_one_region_at_its_height_and_none_spans_a_riser():
    x, _ = _grid()
    stairs = np.where(x < 0.5, 0.0, 0.15 * np.floor((x - 0.5) / 0.3 + 1))
    regions = extract_regions(stairs, RES, np.array([-1.0, -1.0]), P)
    assert len(regions) == 6  # the floor and five treads in the map
    for f in sorted(regions, key=lambda f: f.vertices_xy[:, 0].min()):
        lo, hi = f.vertices_xy[:, 0].min(), f.vertices_xy[:, 0].max()
        z = f.height_at(f.vertices_xy.mean(axis=0))
        np.testing.assert_allclose(f.normal, [0.0, 0.0, 1.0], atol=1e-9)
        # the whole region is at one tread's height: no riser inside it
        assert np.floor((lo - 0.5) / 0.3 + 1) == np.floor((hi - 0.5) / 0.3 + 1) or hi < 0.5
        assert z == pytest.approx(0.15 * max(np.floor((lo - 0.5) / 0.3 + 1), 0.0), abs=1e-9)


def test_a_hull_that_would_cover_a_pit_is_dropped():
    x, y = _grid()
    u_floor = np.where((x > 0.0) & (np.abs(y) < 0.5), np.nan, 0.0)  # a U around a pit
    regions = extract_regions(u_floor, RES, np.array([-1.0, -1.0]), P)
    assert all(not f.contains_xy(0.7, 0.0) for f in regions)
    loose = extract_regions(u_floor, RES, np.array([-1.0, -1.0]),
                            dataclasses.replace(P, min_fill=0.0))
    assert any(f.contains_xy(0.7, 0.0) for f in loose)  # the paper's hull, as it is


def test_the_selection_keeps_the_ground_underfoot_and_the_regions_ahead():
    x, y = _grid(160, 120)
    stones = np.full(x.shape, np.nan)
    centres = [(-0.5, 0.0), (0.3, 0.3), (0.3, -0.3), (1.1, 0.0), (1.9, 0.4), (-0.5, 1.0),
               (2.5, -0.9)]
    for cx, cy in centres:
        stones[(np.abs(x - cx) < 0.2) & (np.abs(y - cy) < 0.2)] = 0.0
    regions = extract_regions(stones, RES, np.array([-1.0, -1.0]), P)
    assert len(regions) == len(centres)
    few = dataclasses.replace(P, max_regions=4)
    kept = select_regions(regions, np.array([-0.5, 0.0]), np.array([0.4, 0.0]), few)
    middles = {tuple(np.round(f.vertices_xy.mean(axis=0), 1)) for f in kept}
    assert len(kept) == 4
    assert (-0.5, 0.0) in middles  # under the robot
    assert (-0.5, 1.0) not in middles and (2.5, -0.9) not in middles  # beside, far aside
    # the map's own motion is the walking direction
    cr = ContourRegions(few)
    cr.process(stones, RES, np.array([-1.0, -1.0]), 0.0)
    cr.process(stones, RES, np.array([-0.96, -1.0]), 0.1)
    assert cr.velocity[0] > 0.05 and abs(cr.velocity[1]) < 1e-9
