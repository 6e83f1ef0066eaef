"""The stepping-stone generator draws every stone inside the bounds of the paper's Table I,
on a 5 x 3 grid with nominal spacing d_min + 21 cm, and its footholds are the stone tops."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from sim import terrain

EPS = 1e-12


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), d_min=st.floats(0.35, 0.70))
def test_stone_samples_stay_inside_table_i_bounds(seed: int, d_min: float) -> None:
    t = terrain.stones(d_min=d_min, seed=seed)
    samples = t.params["samples"]
    assert len(samples) == 15
    assert {(s.row, s.col) for s in samples} == {(r, c) for r in range(5) for c in range(3)}
    stones = t.boxes[1:-1]  # between the start and end platforms
    spacing = d_min + 0.21
    for s, box in zip(samples, stones, strict=True):
        assert d_min - EPS <= s.length <= d_min + 0.05 + EPS
        assert d_min - EPS <= s.width <= d_min + 0.05 + EPS
        assert all(abs(o) <= 0.05 + EPS for o in s.offset[:2])
        assert abs(s.offset[2]) <= 0.075 + EPS
        # the boxes really are those draws
        assert abs(box.center[0] - s.nominal_xy[0] - s.offset[0]) < 1e-9
        assert abs(box.center[1] - s.nominal_xy[1] - s.offset[1]) < 1e-9
        assert abs(box.top_z - s.offset[2]) < 1e-9
        assert abs(box.size[0] - s.length) < 1e-9 and abs(box.size[1] - s.width) < 1e-9
    # nominal grid: spacing d_min + 21 cm in x and y
    xs = sorted({round(s.nominal_xy[0], 9) for s in samples})
    ys = sorted({round(s.nominal_xy[1], 9) for s in samples})
    assert np.allclose(np.diff(xs), spacing) and np.allclose(np.diff(ys), spacing)
    # ground-truth footholds are the top faces less the margin
    m = t.params["margin"]
    for box, fh in zip(t.boxes, t.footholds, strict=True):
        assert np.allclose(fh.vertices[:, 2], box.top_z) and fh.offset == box.top_z
        span = fh.vertices[:, :2].max(axis=0) - fh.vertices[:, :2].min(axis=0)
        assert np.allclose(span, np.array(box.size[:2]) - 2 * m)


def test_same_seed_same_stones_other_seed_other_stones() -> None:
    a, b, c = terrain.stones(seed=3), terrain.stones(seed=3), terrain.stones(seed=4)
    assert a.boxes == b.boxes
    assert a.boxes != c.boxes


def test_ground_truth_footholds_as_halfspaces_and_published(driver_factory) -> None:
    t = terrain.stones(d_min=0.4, seed=5)
    msg = terrain.foothold_set_msg(t, utime=7)
    assert msg.num_footholds == len(t.boxes) == 17 and msg.status == 0
    for fh, box in zip(msg.footholds, t.boxes, strict=True):
        a, b = np.array(fh.A), np.array(fh.b)
        centre = np.array([box.center[0], box.center[1], box.top_z])
        assert np.all(a @ centre <= b)  # the stone's centre is inside
        margin = t.params["margin"]
        edge_out = centre + np.array([box.size[0] / 2 - margin / 2, 0.0, 0.0])
        assert np.any(a @ edge_out > b)  # and the margin strip is not
        assert fh.offset == box.top_z and fh.normal == [0.0, 0.0, 1.0]
    drv = driver_factory("lockstep", {"terrain": "stones", "terrain_seed": 5,
                                      "publish_footholds": True})
    assert "footholds" in drv.node.outputs
    from lcmtypes import foothold_set_t

    got = foothold_set_t.decode(drv.sent["footholds"][0])
    assert got.num_footholds == 17 and got.status_text == "ground truth: stones"
