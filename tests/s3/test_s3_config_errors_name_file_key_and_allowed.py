"""S3 built from a profile: an unknown key or a bad value, in its params or in its gains file
(Table VIII) or in the superpixels' gains file it runs in S3's place, stops the build with a
ConfigError naming the file, the dotted key and what is allowed."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
import yaml

from processes.s3.params import S3Params
from processes.s3.process import Params
from processes.superpixels import SuperpixelParams, SuperpixelSegmenter
from runtime.builder import build_node, process_module, read_config
from runtime.config import HW_CONFIG_DIR
from runtime.params import load
from tests.conftest import assert_names, config_error, one_process


def test_the_profile_as_written_builds_in_its_variant(tmp_path: Path) -> None:
    proc, profile = one_process(tmp_path, "s3", {"variant": "hardware"}, mode="lockstep")
    params, gains = read_config(proc, process_module(proc))
    assert params == Params(variant="hardware")
    assert gains == load(S3Params, HW_CONFIG_DIR / "gains" / "s3.yaml", "hardware")
    assert (gains.k_hyst, gains.inpainting) == (0.6, "ns")  # Table VIII, hardware
    assert build_node(proc, profile).pipeline.params == gains


def test_a_bad_param_names_the_profile_the_key_and_what_is_allowed(tmp_path: Path) -> None:
    err = config_error(tmp_path, "s3", {"varient": "hardware"}, mode="lockstep")
    assert_names(err, tmp_path / "one.yaml", "processes.s3.params.varient", "unknown key",
                 "method, regions_gains, superpixels_gains, variant")
    assert err.problem == "unknown key"
    err = config_error(tmp_path, "s3", {"variant": 2}, mode="lockstep")
    assert (err.file, err.key) == (str(tmp_path / "one.yaml"), "processes.s3.params.variant")
    assert "must be a string" in err.problem
    err = config_error(tmp_path, "s3", {"method": "quadpips"}, mode="lockstep")
    assert_names(err, tmp_path / "one.yaml", "processes.s3.params.method",
                 "'quadpips' is not one of the allowed values", "s3, contours, superpixels")


def test_a_variant_the_gains_file_lacks_names_the_file_and_its_variants(tmp_path: Path) -> None:
    err = config_error(tmp_path, "s3", {"variant": "lab"}, mode="lockstep")
    assert_names(err, tmp_path / "gains.yaml", "variants", "no variant 'lab'",
                 "simulation, hardware")
    assert err.problem == "no variant 'lab'"


@pytest.mark.parametrize(("variant", "change", "key", "problem", "allowed"), [
    ("simulation", lambda d: d.update(k_saef=0.7), "k_saef", "unknown key", None),
    ("hardware", lambda d: d["variants"]["hardware"].update(inpainting="telea"),
     "variants.hardware.inpainting", "'telea' is not one of the allowed values", "ns, lnv"),
    ("simulation", lambda d: d.update(k_hyst=1.5), "k_hyst", "out of range: 1.5",
     "[0.0, 1.0]"),
    ("simulation", lambda d: d.update(margin_kernel_px=2.5), "margin_kernel_px",
     "must be an integer, got 2.5", "[0, 31] px"),
    ("hardware", lambda d: d["variants"]["hardware"].update(inclination_kernel_px=4),
     "variants.hardware.inclination_kernel_px", "must be odd", "3, 5, 7, ... px"),
])
def test_a_bad_gain_names_the_gains_file_the_key_and_what_is_allowed(
        tmp_path: Path, variant: str, change: Any, key: str, problem: str,
        allowed: str | None) -> None:
    err = config_error(tmp_path, "s3", {"variant": variant}, change, mode="lockstep")
    assert_names(err, tmp_path / "gains.yaml", key, problem, allowed,
                 listing="k_safe, log_sigma_px")


def test_the_superpixels_method_builds_from_its_gains_file(tmp_path: Path) -> None:
    proc, profile = one_process(tmp_path, "s3", {"method": "superpixels"}, mode="lockstep")
    node = build_node(proc, profile)
    assert isinstance(node.regions, SuperpixelSegmenter)
    assert node.regions.params == load(SuperpixelParams,
                                       HW_CONFIG_DIR / "gains" / "superpixels.yaml")


@pytest.mark.parametrize(("key", "value", "problem", "allowed"), [
    ("k_dse", 49, "unknown key", None),
    ("k_des", 0, "out of range: 0", "[1, 10000]"),
    ("ransac_threshold_m", -0.01, "out of range: -0.01", "(0.0, inf] m"),
    ("n_iter", 2.5, "must be an integer, got 2.5", "[1, 100]"),
    ("normal_window_px", 4, "must be odd", "1, 3, 5, ... px"),
])
def test_a_bad_superpixels_gain_names_its_file_the_key_and_what_is_allowed(
        tmp_path: Path, key: str, value: Any, problem: str, allowed: str | None) -> None:
    doc = yaml.safe_load((HW_CONFIG_DIR / "gains" / "superpixels.yaml").read_text())
    doc[key] = value
    gains = tmp_path / "superpixels.yaml"
    gains.write_text(yaml.safe_dump(doc))
    err = config_error(tmp_path, "s3", {"method": "superpixels",
                                        "superpixels_gains": str(gains)}, mode="lockstep")
    assert_names(err, gains, key, problem, allowed, listing="k_des, margin_px")
