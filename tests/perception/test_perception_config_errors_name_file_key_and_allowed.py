"""Perception built from a profile: an unknown key or a bad value, in its params (the camera
mount) or in its gains file (the elevation map, Table VIII), stops the build with a
ConfigError naming the file, the dotted key and what is allowed."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
import yaml

from processes.perception.elevation_map import ElevationMapParams
from processes.perception.process import Params
from runtime.builder import build_node, process_module, read_config
from runtime.config import HW_CONFIG_DIR, load_profile
from runtime.errors import ConfigError
from runtime.params import load

PROFILE = """\
include: [{hw}/hosts.yaml, {hw}/channels.yaml]
mode: lockstep
processes:
  perception:
    host: laptop
    module: processes.perception.process
    inputs: {{depth: depth, state: network_state}}
    outputs: {{elevation_map: elevation_map}}
    gains: {gains}
    params: {params}
launch: [perception]
"""
GAINS = HW_CONFIG_DIR / "gains" / "elevation_map.yaml"


def _proc(tmp_path: Path, params: dict[str, Any], gains: Any = None):  # type: ignore[no-untyped-def]
    """The profile's perception, with a copy of the elevation map's gains changed by ``gains``."""
    doc = yaml.safe_load(GAINS.read_text())
    if gains is not None:
        gains(doc)
    gfile = tmp_path / "elevation_map.yaml"
    gfile.write_text(yaml.safe_dump(doc, sort_keys=False))
    pfile = tmp_path / "profile.yaml"
    pfile.write_text(PROFILE.format(hw=HW_CONFIG_DIR, gains=gfile, params=params))
    profile = load_profile(pfile)
    return profile.processes["perception"], profile, pfile, gfile


def test_the_profile_as_written_reads_its_params_and_gains(tmp_path: Path) -> None:
    proc, _, _, _ = _proc(tmp_path, {"variant": "hardware", "camera_pose": "frame",
                                     "camera_mount_pos_m": [0.1, 0, 0.03]})
    params, gains = read_config(proc, process_module(proc))
    assert params == Params(variant="hardware", camera_pose="frame",
                            camera_mount_pos_m=(0.1, 0.0, 0.03))
    assert gains == load(ElevationMapParams, GAINS, "hardware")
    assert (gains.length_m, gains.resolution_m) == (3.0, 0.03)  # Table VIII, hardware


ALL_PARAMS = ("camera_mount_pos_m, camera_pitch_down_deg, camera_pose, crop_legs, "
              "drift_correction, variant")


@pytest.mark.parametrize(("params", "key", "problem", "allowed"), [
    ({"camera_yaw_deg": 10.0}, "camera_yaw_deg", "unknown key", ALL_PARAMS),
    ({"camera_pose": "lidar"}, "camera_pose", "'lidar' is not one of the allowed values",
     "estimated, frame"),
    ({"camera_pitch_down_deg": 120}, "camera_pitch_down_deg", "out of range: 120",
     "[-90.0, 90.0] deg"),
    ({"camera_mount_pos_m": [0.09, 0.0]}, "camera_mount_pos_m", "must be a list of 3", None),
    ({"crop_legs": 1}, "crop_legs", "must be true or false", "true, false"),
])
def test_a_bad_param_names_the_profile_the_key_and_what_is_allowed(
        tmp_path: Path, params: dict[str, Any], key: str, problem: str,
        allowed: str | None) -> None:
    proc, profile, pfile, _ = _proc(tmp_path, params)
    with pytest.raises(ConfigError) as err:
        build_node(proc, profile)
    assert (err.value.file, err.value.key) == (str(pfile), f"processes.perception.params.{key}")
    assert problem in err.value.problem and err.value.allowed == allowed


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
    proc, profile, _, gfile = _proc(tmp_path, {"variant": variant}, change)
    with pytest.raises(ConfigError) as err:
        build_node(proc, profile)
    assert (err.value.file, err.value.key) == (str(gfile), key)
    assert problem in err.value.problem
    if allowed is None:  # an unknown key: every field of the gains, alphabetically
        assert err.value.allowed is not None and "resolution_m" in err.value.allowed
    else:
        assert err.value.allowed == allowed
