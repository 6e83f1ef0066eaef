"""Terrain and sim gains YAML files: the shipped ones load; each kind of mistake raises a
ConfigError that names the file, the key and what is allowed."""

from __future__ import annotations

from pathlib import Path

import pytest

from runtime.errors import ConfigError
from runtime.params import load
from sim.process import SimGains, settings_of
from sim.terrain import load_terrain

from .conftest import HW_CONFIG


@pytest.mark.parametrize("name", ["flat", "stairs", "beam", "stones", "blocks", "ramped_stones",
                                  "winding_beam"])
def test_shipped_terrains_load(name: str) -> None:
    t = load_terrain(HW_CONFIG / "terrains" / f"{name}.yaml")
    assert t.name == name and t.footholds
    if name == "stairs":
        assert t.params["rise"] == 0.15 and t.params["depth"] == 0.27
        assert [round(b.top_z, 9) for b in t.boxes][:3] == [0.15, 0.30, 0.45]
    if name == "beam":
        assert t.boxes[1].size[1] == 0.23


@pytest.mark.parametrize("text, key, words", [
    ("terrain: lava\n", "terrain", "allowed: flat, stairs, beam, stones, blocks, "
     "ramped_stones, winding_beam, boxes"),
    ("foothold_margin: 0.1\n", "terrain", "is required (allowed: flat, stairs"),
    ("terrain: stairs\nparams: {rise: -0.1}\n", "params.rise", "out of range: -0.1 (allowed: "
     "(0.0, inf])"),
    ("terrain: stairs\nparams: {rise: high}\n", "params.rise", "must be a number"),
    ("terrain: stairs\nparams: {count: 2.5}\n", "params.count", "must be an integer"),
    ("terrain: stairs\nparams: {steps: 3}\n", "params.steps",
     "allowed: count, depth, landing, rise, start_length, width"),
    ("terrain: stones\nparams: {seed: 3}\n", "params.seed", "allowed: d_min, pit_depth, platform"),
    ("terrain: beam\nseed: 3\n", "seed", "not random"),
    ("terrain: stones\nseed: -1\n", "seed", "out of range"),
    ("terrain: flat\ncolour: red\n", "colour", "unknown key"),
    ("terrain: stairs\nground_z: 1\n", "ground_z", "unknown key"),
    ("terrain: boxes\nseed: 1\nboxes: [{center: [0, 0, 0], size: [1, 1, 1]}]\n", "seed",
     "unknown key"),
    ("terrain: stones\nparams: {d_min: .nan}\n", "params.d_min", "out of range: nan"),
    ("terrain: boxes\nboxes: [{center: [0, 0, 0]}]\n", "boxes[0].size", "is required"),
    ("terrain: boxes\nboxes: []\n", "boxes", "non-empty"),
    ("terrain: boxes\nboxes: [{center: [0, 0], size: [1, 1, 1]}]\n", "boxes[0].center",
     "list of 3"),
    ("terrain: boxes\nboxes: [{center: [0, 0, 0], size: [1, 0, 1]}]\n", "boxes[0].size[1]",
     "out of range: 0"),
    ("terrain: blocks\nparams: {size_min: 0.9, size_max: 0.3}\n", "params.size_min", "above"),
    ("terrain: blocks\nparams: {area: [1, 0, 0, 1]}\n", "params.area", "x_min < x_max"),
    ("terrain: ramped_stones\nparams: {max_tilt_deg: 40}\n", "params.max_tilt_deg",
     "(0, 30] deg"),
    ("terrain: winding_beam\nparams: {turn_min_deg: 35}\n", "params.turn_min_deg",
     "[0, 30.0] deg"),
    ("terrain: winding_beam\nparams: {max_heading_deg: 10}\n", "params.max_heading_deg",
     "[15.0, 90) deg"),
    ("terrain: winding_beam\nparams: {segments: 2.5}\n", "params.segments",
     "must be an integer"),
    ("terrain: beam\nseed: 3\n", "seed", "stones, blocks, ramped_stones, winding_beam"),
    ("- just\n- a list\n", "<top level>", "mapping"),
    ("terrain: [unclosed\n", "<file>", "not valid YAML"),
])
def test_bad_terrain_files_name_file_and_key(tmp_path: Path, text: str, key: str,
                                             words: str) -> None:
    f = tmp_path / "bad.yaml"
    f.write_text(text)
    with pytest.raises(ConfigError) as info:
        load_terrain(f)
    err = info.value
    assert err.file == str(f) and err.key == key, str(err)
    assert words in str(err)
    assert str(f) in str(err)


def test_missing_terrain_file_is_a_config_error(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="file not found"):
        load_terrain(tmp_path / "nope.yaml")


@pytest.mark.parametrize("text, key", [
    ("watchdog_ms: 0\n", "watchdog_ms"),
    ("holder: {release_on: later}\n", "holder.release_on"),
    ("holder: {timeconst_s: -1}\n", "holder.timeconst_s"),
    ("camera: {decimation: 0}\n", "camera.decimation"),
    ("camera: {mount_pos_m: [0.09, 0, 0.02]}\n", "camera.mount_pos_m"),  # (the robot's)
    ("camera: {min_range_m: 7.0}\n", "camera.min_range_m"),
    ("camera: {fov: 90}\n", "camera.fov"),
    ("lockstep: {timeout_s: 0}\n", "lockstep.timeout_s"),
    ("lockstep: {min_timeout_s: 0.5}\n", "lockstep.min_timeout_s"),
    ("physics: {pelvis_height_m: 2.0}\n", "physics.pelvis_height_m"),
    ("push: {force_n: [1, 2, 3]}\n", "push.after_release_s"),
])
def test_bad_sim_gains_name_file_and_key(tmp_path: Path, text: str, key: str) -> None:
    f = tmp_path / "sim.yaml"
    f.write_text(text)
    with pytest.raises(ConfigError) as info:
        load(SimGains, f)
    assert info.value.key == key and info.value.file == str(f)


def test_shipped_gains_load() -> None:
    s = settings_of(load(SimGains, HW_CONFIG / "gains" / "sim.yaml"))
    assert s.sim.watchdog_s == 0.010 and s.camera.out_width == 106 and s.camera.out_height == 60
