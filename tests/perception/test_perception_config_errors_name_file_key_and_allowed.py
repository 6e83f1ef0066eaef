"""Perception built from a profile: an unknown key or a bad value, in its params (where the
camera pose comes from, the crops) or in its gains file (the elevation map, Table VIII),
stops the build with a ConfigError naming the file, the dotted key and what is allowed."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from processes.perception.elevation_map import ElevationMapParams
from processes.perception.process import Params
from runtime.builder import process_module, read_config
from runtime.config import HW_CONFIG_DIR
from runtime.params import load
from tests.conftest import assert_names, config_error, one_process

GAINS = HW_CONFIG_DIR / "gains" / "elevation_map.yaml"


def test_the_profile_as_written_reads_its_params_and_gains(tmp_path: Path) -> None:
    proc, _ = one_process(tmp_path, "perception", {"variant": "hardware", "camera_pose": "frame",
                                                   "crop_legs": False}, mode="lockstep")
    params, gains = read_config(proc, process_module(proc))
    assert params == Params(variant="hardware", camera_pose="frame", crop_legs=False)
    assert gains == load(ElevationMapParams, GAINS, "hardware")
    assert (gains.length_m, gains.resolution_m) == (3.0, 0.03)  # Table VIII, hardware


ALL_PARAMS = "camera_pose, crop_legs, drift_correction, variant"


@pytest.mark.parametrize(("params", "key", "problem", "allowed"), [
    ({"camera_yaw_deg": 10.0}, "camera_yaw_deg", "unknown key", ALL_PARAMS),
    ({"camera_pose": "lidar"}, "camera_pose", "'lidar' is not one of the allowed values",
     "estimated, frame"),
    # the camera's mount is the robot's (runtime.robot), not a param
    ({"camera_pitch_down_deg": 50.0}, "camera_pitch_down_deg", "unknown key", ALL_PARAMS),
    ({"crop_legs": 1}, "crop_legs", "must be true or false", "true, false"),
])
def test_a_bad_param_names_the_profile_the_key_and_what_is_allowed(
        tmp_path: Path, params: dict[str, Any], key: str, problem: str,
        allowed: str | None) -> None:
    err = config_error(tmp_path, "perception", params, mode="lockstep")
    assert_names(err, tmp_path / "one.yaml", f"processes.perception.params.{key}", problem,
                 allowed)


@pytest.mark.parametrize(("variant", "change", "key", "problem", "allowed"), [
    ("simulation", lambda d: d.update(resolution=0.02), "resolution", "unknown key", None),
    ("hardware", lambda d: d["variants"]["hardware"].update(decimation=0),
     "variants.hardware.decimation", "out of range: 0", "[1, 16] px"),
    ("simulation", lambda d: d.update(length_m=0.1), "length_m", "out of range: 0.1",
     "(0.1, 20.0] m"),
    ("simulation", lambda d: d.update(min_depth_m=3.5), "max_depth_m",
     "must exceed min_depth_m", "> 3.5 m"),
    ("lab", None, "variants", "no variant 'lab'", "simulation, hardware"),
])
def test_a_bad_gain_names_the_gains_file_the_key_and_what_is_allowed(
        tmp_path: Path, variant: str, change: Any, key: str, problem: str,
        allowed: str | None) -> None:
    err = config_error(tmp_path, "perception", {"variant": variant}, change, mode="lockstep")
    assert_names(err, tmp_path / "gains.yaml", key, problem, allowed, listing="resolution_m")
