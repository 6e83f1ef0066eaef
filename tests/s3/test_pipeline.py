"""S3 pipeline end to end: plane fits, bad input, IoU metrics, config."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from processes.s3 import S3Params, S3Pipeline
from processes.s3.metrics import coverage_mask, frame_iou
from processes.s3.planes import fit_planes
from runtime.errors import ConfigError
from runtime.params import load
from tools.testbed import s3_scenes as syn

RES = 0.025
SHAPE = (100, 100)
ORIGIN = np.array([1.3, -0.7])          # an off-centre map: world frame matters
REPO = Path(__file__).resolve().parents[2]


def _inside_map(xy: np.ndarray) -> bool:
    hi = ORIGIN + (np.array(SHAPE[::-1]) - 1) * RES
    return bool(np.all(xy >= ORIGIN - 1e-9) and np.all(xy <= hi + 1e-9))


@pytest.mark.parametrize("slope", [(0.2, -0.1), (0.0, 0.35), (-0.3, 0.3)])
def test_planes_fit_a_tilted_surface(slope: tuple[float, float]) -> None:
    sx, sy = slope
    z0 = 0.4
    e = syn.render(syn.tilted(sx, sy, z0), SHAPE, RES, ORIGIN, noise_std=0.002,
                   rng=np.random.default_rng(4))
    result = S3Pipeline().process(e, RES, ORIGIN)
    assert result.status == "ok" and len(result.footholds) == 1
    f = result.footholds[0]
    truth = np.array([-sx, -sy, 1.0]) / np.sqrt(1 + sx * sx + sy * sy)
    assert np.degrees(np.arccos(np.clip(f.normal @ truth, -1, 1))) < 0.5
    verts = f.vertices
    assert np.allclose(verts[:, 2], z0 + sx * verts[:, 0] + sy * verts[:, 1], atol=0.005)
    assert result.plane_rms_m[0] < 0.004


def test_planes_are_fitted_per_polygon_on_stairs() -> None:
    e = syn.render(syn.stairs(start_x=1.6, rise=0.12, run=0.6, steps=3), SHAPE, RES, ORIGIN)
    footholds = S3Pipeline(S3Params(k_hyst=0.0)).process(e, RES, ORIGIN).footholds
    heights = sorted(round(f.offset / f.normal[2], 3) for f in footholds)
    assert len(footholds) >= 3
    for h in heights:
        assert min(abs(h - t) for t in (0.0, 0.12, 0.24, 0.36)) < 0.005
    for f in footholds:
        assert f.normal[2] == pytest.approx(1.0, abs=1e-4)


def test_fit_planes_handles_several_disjoint_polygons_at_once() -> None:
    e = np.zeros(SHAPE)
    e[:, 50:] = 0.2 + 0.1 * np.arange(50) * RES          # a slope on the right half
    left = np.array([[5, 5], [40, 5], [40, 90], [5, 90]], float)
    right = np.array([[60, 5], [95, 5], [95, 90], [60, 90]], float)
    n, d, rms = fit_planes(e, [left, right], RES, ORIGIN)
    assert np.allclose(n[0], [0, 0, 1]) and d[0] == pytest.approx(0.0, abs=1e-9)
    assert n[1] @ np.array([-0.1, 0, 1]) / np.linalg.norm([-0.1, 0, 1]) == pytest.approx(1.0)
    assert np.all(rms < 1e-6)


def test_empty_map_gives_no_footholds_and_says_so() -> None:
    r = S3Pipeline().process(np.empty((0, 0)), RES, ORIGIN)
    assert r.status == "empty map" and r.footholds == [] and not r.ok


def test_all_nan_map_gives_no_footholds_and_says_so() -> None:
    r = S3Pipeline().process(np.full(SHAPE, np.nan), RES, ORIGIN)
    assert r.status == "all NaN" and r.footholds == [] and r.safe_mask.shape == SHAPE


@pytest.mark.parametrize("resolution, origin, elevation", [
    (0.0, ORIGIN, np.zeros(SHAPE)),
    (float("nan"), ORIGIN, np.zeros(SHAPE)),
    (RES, np.array([np.nan, 0.0]), np.zeros(SHAPE)),
    (RES, ORIGIN, np.zeros(10)),
    (RES, ORIGIN, np.array([["a", "b"]])),
    (RES, ORIGIN, np.zeros(SHAPE, complex)),
    ("fine", ORIGIN, np.zeros(SHAPE)),
    (None, ORIGIN, np.zeros(SHAPE)),
    (RES, "here", np.zeros(SHAPE)),
    (RES, ORIGIN, [[0.0, 1.0], [2.0]]),
])
def test_malformed_input_is_refused_with_a_status(resolution: object, origin: object,
                                                  elevation: object) -> None:
    r = S3Pipeline().process(elevation, resolution, origin)
    assert r.status.startswith("bad input") and r.footholds == []


def test_stale_map_keeps_the_previous_footholds() -> None:
    pipe = S3Pipeline()
    e = syn.render(syn.flat(), SHAPE, RES, ORIGIN)
    first = pipe.process(e, RES, ORIGIN, map_time_s=1.0, now_s=1.01)
    assert first.status == "ok"
    again = pipe.process(e, RES, ORIGIN, map_time_s=1.0, now_s=1.05)     # same map again
    assert again.status == "stale map" and again.footholds is first.footholds
    old = pipe.process(e, RES, ORIGIN, map_time_s=1.1, now_s=5.0)        # far too old
    assert old.status == "stale map" and len(old.footholds) == 1
    fresh = pipe.process(e, RES, ORIGIN, map_time_s=1.2, now_s=1.21)
    assert fresh.status == "ok"


def test_stale_map_before_any_result_is_empty() -> None:
    r = S3Pipeline().process(np.zeros(SHAPE), RES, ORIGIN, map_time_s=0.0, now_s=10.0)
    assert r.status == "stale map" and r.footholds == []


def test_no_safe_terrain_is_reported() -> None:
    e = syn.render(syn.tilted(1.5, 0.0), SHAPE, RES, ORIGIN)    # 56 degrees: all unsafe
    r = S3Pipeline().process(e, RES, ORIGIN)
    assert r.status == "no safe terrain" and r.ok and r.footholds == []


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 10_000), st.floats(0.0, 0.9), st.sampled_from(["ns", "lnv"]))
def test_garbage_maps_never_crash_nor_leave_the_map(seed: int, nan_fraction: float,
                                                    method: str) -> None:
    rng = np.random.default_rng(seed)
    e = rng.normal(0.0, rng.choice([0.001, 0.05, 3.0]), SHAPE)
    e[rng.random(SHAPE) < nan_fraction] = np.nan
    e[rng.random(SHAPE) < 0.01] = np.inf
    pipe = S3Pipeline(S3Params(inpainting=method))
    for _ in range(2):
        r = pipe.process(e, RES, ORIGIN)
        assert r.ok or r.status == "all NaN"
        for f in r.footholds:
            assert _inside_map(f.vertices_xy)
            assert np.all(np.isfinite(f.normal)) and np.isfinite(f.offset)
            assert np.all(f.A @ np.append(f.vertices_xy.mean(axis=0), 0.0) <= f.b + 1e-9)


def test_partially_unknown_map_is_inpainted_and_segmented() -> None:
    e = syn.render(syn.flat(0.05), SHAPE, RES, ORIGIN, nan_holes=6, hole_radius_m=0.1,
                   rng=np.random.default_rng(5))
    assert np.isnan(e).any()
    for method in ("ns", "lnv"):
        r = S3Pipeline(S3Params(inpainting=method)).process(e, RES, ORIGIN)
        assert r.status == "ok" and r.safe_mask.all() and len(r.footholds) == 1


def test_iou_is_one_for_the_same_terrain_seen_from_a_moved_map() -> None:
    terrain = syn.stairs(start_x=1.8, rise=0.1, run=0.5, steps=3)   # no edge near a border
    shifted = ORIGIN + np.array([3 * RES, -2 * RES])
    pipe_a, pipe_b = S3Pipeline(), S3Pipeline()
    ra = pipe_a.process(syn.render(terrain, SHAPE, RES, ORIGIN), RES, ORIGIN)
    rb = pipe_b.process(syn.render(terrain, SHAPE, RES, shifted), RES, shifted)
    # away from the map edges the masks agree; IoU over shared cells is close to 1
    assert frame_iou(ra.safe_mask, ORIGIN, rb.safe_mask, shifted, RES) > 0.97
    cov_a = coverage_mask([f.vertices_xy for f in ra.footholds], SHAPE, RES, ORIGIN)
    cov_b = coverage_mask([f.vertices_xy for f in rb.footholds], SHAPE, RES, shifted)
    assert frame_iou(cov_a, ORIGIN, cov_b, shifted, RES) > 0.8
    # and a disjoint pair has IoU 0
    left = np.zeros(SHAPE, np.uint8)
    left[:, :50] = 1
    assert frame_iou(left, ORIGIN, 1 - left, ORIGIN, RES) == 0.0


def test_parameters_load_from_both_variants() -> None:
    path = REPO / "hw_config" / "gains" / "s3.yaml"
    sim = load(S3Params, path)
    hw = load(S3Params, path, "hardware")
    assert (sim.k_hyst, sim.inpainting) == (0.4, "lnv")       # Table VIII, simulation
    assert (hw.k_hyst, hw.inpainting) == (0.6, "ns")          # Table VIII, hardware
    assert sim.concavity_limit_m == 0.25 and sim.k_safe == 0.7
    assert load(S3Params, path, "simulation") == sim


@pytest.mark.parametrize("key, value, words", [
    ("k_hyst", 1.5, "out of range"),
    ("inpainting", "telea", "not one of the allowed values"),
    ("inclination_kernel_px", 4, "odd"),
    ("margin_kernel_px", 2.5, "integer"),
    ("k_saef", 0.7, "unknown key"),
    ("alpha_curve", "five", "number"),
])
def test_bad_parameter_raises_config_error_naming_the_key(tmp_path: Path, key: str,
                                                           value: object, words: str) -> None:
    path = tmp_path / "s3.yaml"
    text = "variants:\n  simulation:\n"
    text += f"    {key}: {value!r}\n".replace("'", '"')
    path.write_text(text)
    with pytest.raises(ConfigError) as info:
        load(S3Params, path, "simulation")
    assert info.value.key == f"variants.simulation.{key}" and words in str(info.value)
    assert str(path) in str(info.value)


def test_unknown_variant_raises_config_error(tmp_path: Path) -> None:
    path = tmp_path / "s3.yaml"
    path.write_text("default_variant: lab\nvariants:\n  simulation: {}\n")
    with pytest.raises(ConfigError, match="no variant 'lab'"):
        load(S3Params, path)
