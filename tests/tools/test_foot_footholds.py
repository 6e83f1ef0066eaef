"""The experiments' ground-truth footholds are shrunk for Cassie's foot (the paper's ground
truth "accounts for the width and length of the foot separately"); footsteps are judged on
the faces, not on the shrunk footholds."""

from __future__ import annotations

import numpy as np

from runtime.config import HW_CONFIG_DIR
from runtime.geometry import Foothold
from sim.terrain import Box, load_terrain


def _top_face(box: Box) -> Foothold:
    """The box's whole top face as a foothold."""
    return Foothold.from_ccw(box.top_corners()[:, :2], (0.0, 0.0, 1.0), box.top_z)


def test_a_foot_centred_in_a_stairs_foothold_stands_wholly_on_its_step():
    t = load_terrain(HW_CONFIG_DIR / "terrains" / "stairs.yaml")
    hl, hw = t.params["foot_half_size"]
    assert (hl, hw) == (0.10, 0.02)
    assert len(t.footholds) == len(t.surfaces) == 7
    for fh, face in zip(t.footholds, t.surfaces, strict=True):
        for x, y, _ in fh.vertices:  # corners of the foothold: the worst foot centres
            for dx in (-hl, hl):
                for dy in (-hw, hw):
                    assert face.contains_xy(x + dx, y + dy)
    # 27 cm treads: 27 - 2 (10 + 2) cm = 3 cm of foot centres per tread
    tread = t.footholds[1].vertices[:, 0]
    assert np.isclose(tread.max() - tread.min(), 0.03)
    assert t.landing_surfaces == t.surfaces


def test_erosion_is_per_axis_and_drops_faces_too_small_for_the_foot():
    face = _top_face(Box((0.0, 0.0, -0.5), (0.4, 0.3, 1.0)))
    small = face.eroded(0.1, 0.02)
    assert small is not None
    v = small.vertices
    np.testing.assert_allclose([v[:, 0].min(), v[:, 0].max()], [-0.1, 0.1])
    np.testing.assert_allclose([v[:, 1].min(), v[:, 1].max()], [-0.13, 0.13])
    np.testing.assert_allclose(v[:, 2], 0.0)
    assert face.eroded(0.21, 0.0) is None
    # a yawed face: every corner of the foot at every foothold corner stays inside
    yawed = _top_face(Box((1.0, 0.5, -0.5), (0.5, 0.4, 1.0), yaw=0.4))
    er = yawed.eroded(0.1, 0.02)
    assert er is not None
    for x, y, _ in er.vertices:
        for dx in (-0.1, 0.1):
            for dy in (-0.02, 0.02):
                assert yawed.contains_xy(x + dx - 1e-9 * np.sign(dx), y + dy - 1e-9 * np.sign(dy))


def test_terrains_without_a_foot_size_keep_their_footholds():
    t = load_terrain(HW_CONFIG_DIR / "terrains" / "flat.yaml")
    assert t.surfaces == () and t.landing_surfaces == t.footholds
