"""S3 segmentation (Section VI-A): flat ground, step edges, the criteria and the hysteresis."""

from __future__ import annotations

import numpy as np
import pytest

from processes.s3 import S3Params, S3Pipeline
from processes.s3.segmentation import (
    Segmenter,
    curvature_criterion,
    inclination_criterion,
    inpaint,
    shift_mask,
)
from tools.testbed import s3_scenes as syn

RES = 0.025
SHAPE = (100, 100)
ORIGIN = -0.5 * (np.array(SHAPE[::-1]) - 1) * RES


def _col(x: float) -> int:
    """Column whose centre is nearest world x."""
    return round((x - ORIGIN[0]) / RES)


def test_flat_map_is_one_polygon_covering_it() -> None:
    e = syn.render(syn.flat(0.1), SHAPE, RES, ORIGIN, noise_std=0.003,
                   rng=np.random.default_rng(1))
    result = S3Pipeline(S3Params()).process(e, RES, ORIGIN)
    assert result.status == "ok"
    assert result.safe_mask.all()
    assert len(result.footholds) == 1
    poly = result.footholds[0].vertices_xy
    # the polygon runs through the border cells' centres: the whole map less half a cell
    span = (SHAPE[0] - 1) * RES
    assert result.footholds[0].area_m2 == pytest.approx(span * span, rel=0.02)
    assert poly[:, 0].min() == pytest.approx(ORIGIN[0], abs=RES)
    assert poly[:, 1].max() == pytest.approx(ORIGIN[1] + span, abs=RES)
    assert abs(result.footholds[0].offset - 0.1) < 0.005


@pytest.mark.parametrize("height", [0.1, 0.15])
def test_step_edge_is_unsafe_below_and_safe_on_top(height: float) -> None:
    e = syn.render(syn.step(0.0, height), SHAPE, RES, ORIGIN, noise_std=0.002,
                   rng=np.random.default_rng(2))
    pipe = S3Pipeline(S3Params(k_hyst=0.0))
    mask = pipe.process(e, RES, ORIGIN).safe_mask
    rows = slice(10, 90)
    edge = _col(0.0)                     # first column on top (x >= 0)
    # the foot of the step (10 cm) is unsafe, as is the edge itself
    assert not mask[rows, _col(-0.1):edge].any()
    assert not mask[rows, edge:edge + 2].any()
    # the top is safe from 10 cm past the edge, the bottom only further away
    assert mask[rows, _col(0.1):].all()
    assert mask[rows, :_col(-0.3)].all()
    # the criterion itself is asymmetric (Fig. 9): curvature flags only the lower side
    score = Segmenter(0.0, 0.7, 4, 3, 2.0, 5.0, 5).score(e, RES)
    unsafe = score[50] < 0.7
    below = np.count_nonzero(unsafe[:edge])
    above = np.count_nonzero(unsafe[edge:])
    assert below > above >= 1


def test_curvature_criterion_penalises_only_cells_below_their_surroundings() -> None:
    pit = syn.render(syn.flat(), SHAPE, RES, ORIGIN)
    bump = pit.copy()
    pit[45:55, 45:55] -= 0.1
    bump[45:55, 45:55] += 0.1
    c_pit = curvature_criterion(pit, RES, 2.0, 5.0)
    c_bump = curvature_criterion(bump, RES, 2.0, 5.0)
    assert c_pit[46:54, 46:54].max() < 0.49      # the floor of a 10 cm pit: unsafe
    assert c_bump[45:55, 45:55].min() > 0.6      # the top of a bump: penalised far less
    assert c_bump[47:53, 47:53].min() == pytest.approx(1.0)   # no bonus, no penalty
    assert c_bump.min() < 0.5                    # but the foot around the bump is unsafe
    assert c_pit.max() <= 1.0


@pytest.mark.parametrize("degrees", [0.0, 20.0, 33.0, 45.0])
def test_inclination_criterion_is_cos_squared_of_the_slope(degrees: float) -> None:
    e = syn.render(syn.tilted(np.tan(np.radians(degrees)), 0.0, 0.5), SHAPE, RES, ORIGIN)
    c = inclination_criterion(e, RES, 5)
    assert np.allclose(c, np.cos(np.radians(degrees)) ** 2, atol=1e-3)


def test_inclination_normal_is_the_covariance_normal_not_the_gradient() -> None:
    # a 5 x 5 window straddling a 15 cm step: PCA sees a steep wall, more than the LSQ slope
    e = syn.render(syn.step(0.0, 0.15), SHAPE, RES, ORIGIN)
    c = inclination_criterion(e, RES, 5)
    r, col = 50, _col(0.0)
    win = e[r - 2:r + 3, col - 2:col + 3]
    xs, ys = np.meshgrid(np.arange(5) * RES, np.arange(5) * RES)
    pts = np.column_stack((xs.ravel(), ys.ravel(), win.ravel()))
    _, v = np.linalg.eigh(np.cov(pts.T, bias=True))
    assert c[r, col] == pytest.approx(v[2, 0] ** 2, abs=1e-4)


def test_hysteresis_keeps_a_flickering_pixel() -> None:
    seg = Segmenter(0.4, 0.7, 4, 3, 2.0, 5.0, 5)
    score = np.ones(SHAPE)
    score[50, 50] = 0.5                   # below k_safe, above k_safe - k_hyst
    previous = np.ones(SHAPE, np.uint8)
    assert seg.threshold(score, previous)[50, 50] == 1
    assert seg.threshold(score, None)[50, 50] == 0
    score[50, 50] = 0.2                   # a real obstacle still gets through
    assert seg.threshold(score, previous)[50, 50] == 0


def test_hysteresis_keeps_a_flickering_pit_through_the_pipeline() -> None:
    base = syn.render(syn.flat(), SHAPE, RES, ORIGIN)
    seg = Segmenter(0.4, 0.7, 4, 3, 2.0, 5.0, 5)
    depth = None
    for d in np.linspace(0.005, 0.1, 40):   # a 3 x 3 pit whose score lies in (0.3, 0.7)
        e = base.copy()
        e[49:52, 49:52] -= d
        if 0.35 < seg.score(e, RES).min() < 0.65:
            depth = d
            break
    assert depth is not None
    flicker = base.copy()
    flicker[49:52, 49:52] -= depth

    def run(k_hyst: float) -> list[bool]:
        pipe = S3Pipeline(S3Params(k_hyst=k_hyst))
        safe = []
        for k in range(6):
            r = pipe.process(flicker if k % 2 else base, RES, ORIGIN)
            safe.append(bool(r.safe_mask[50, 50]))
        return safe

    assert run(0.4) == [True] * 6
    assert run(0.0) == [True, False, True, False, True, False]


def test_previous_segmentation_moves_with_the_map() -> None:
    prev = np.zeros((10, 10), np.uint8)
    prev[4, 6] = 1
    moved = shift_mask(prev, np.zeros(2), np.array([2 * RES, -RES]), RES)
    # world point of cell (4, 6) is now cell (4 + 1, 6 - 2)
    assert moved[5, 4] == 1 and moved.sum() == 1


def test_lnv_inpainting_takes_the_least_neighbouring_value() -> None:
    e = np.full((20, 20), 0.3)
    e[:, :10] = 0.1
    e[5:15, 8:12] = np.nan
    filled = inpaint(e, "lnv")
    assert np.isfinite(filled).all()
    assert np.allclose(filled[5:15, 8:12], 0.1)   # the lowest rim value: conservative
    assert np.allclose(filled[:5], e[:5])           # measured cells untouched
    e2 = np.full((20, 20), 0.3)
    e2[8:12, 8:12] = np.nan
    e2[7, 7] = 0.05                                 # one low cell on the rim
    e2[2:4, 2:4] = np.nan                           # a separate hole keeps its own rim
    filled2 = inpaint(e2, "lnv")
    assert np.allclose(filled2[8:12, 8:12], 0.05) and np.allclose(filled2[2:4, 2:4], 0.3)


def test_lnv_with_the_lowest_layer_keeps_an_occluded_gap_low() -> None:
    # two stones at 0.0 with a gap whose floor was never seen; the far wall was, down to -0.4
    e = np.zeros((20, 30))
    e[:, 12:17] = np.nan
    lowest = e.copy()
    lowest[:, 17] = -0.4                            # the far stone's edge cells saw its wall
    assert np.allclose(inpaint(e, "lnv")[:, 12:17], 0.0)        # blind LNV: the gap vanishes
    filled = inpaint(e, "lnv", lowest=lowest)
    assert np.allclose(filled[:, 12:17], -0.4)                  # with it: a gap again
    assert np.allclose(filled[:, 17], 0.0)                      # measured heights unchanged


def test_ns_inpainting_continues_a_plane() -> None:
    e = syn.render(syn.tilted(0.1, 0.05, 0.2), SHAPE, RES, ORIGIN)
    truth = e.copy()
    e[40:50, 40:50] = np.nan
    filled = inpaint(e, "ns", 3)
    assert np.isfinite(filled).all()
    assert np.abs(filled[40:50, 40:50] - truth[40:50, 40:50]).max() < 0.01
