"""Terrain and sim gains YAML files: the shipped ones load; each kind of mistake raises a
ConfigError that names the file, the key and what is allowed."""

from __future__ import annotations

from pathlib import Path

import pytest

from runtime.errors import ConfigError
from sim.process import load_gains
from sim.terrain import load_terrain

from .conftest import HW_CONFIG


@pytest.mark.parametrize("name", ["flat", "stairs", "beam", "stones", "blocks"])
def test_shipped_terrains_load(name: str) -> None:
    t = load_terrain(HW_CONFIG / "terrains" / f"{name}.yaml")
    assert t.name == name and t.footholds
    if name == "stairs":
        assert t.params["rise"] == 0.15 and t.params["depth"] == 0.27
        assert [round(b.top_z, 9) for b in t.boxes][:3] == [0.15, 0.30, 0.45]
    if name == "beam":
        assert t.boxes[1].size[1] == 0.23


@pytest.mark.parametrize("text, key, words", [
    ("terrain: lava\n", "terrain", "allowed: flat, stairs, beam, stones, blocks, boxes"),
    ("terrain: stairs\nparams: {rise: -0.1}\n", "params.rise", "must be > 0"),
    ("terrain: stairs\nparams: {rise: high}\n", "params.rise", "must be a number"),
    ("terrain: stairs\nparams: {count: 2.5}\n", "params.count", "must be an integer"),
    ("terrain: stairs\nparams: {steps: 3}\n", "params.steps", "allowed: rise, depth, count"),
    ("terrain: beam\nseed: 3\n", "seed", "not random"),
    ("terrain: flat\ncolour: red\n", "colour", "unknown key"),
    ("terrain: stones\nparams: {d_min: .nan}\n", "params.d_min", "must be a number"),
    ("terrain: boxes\nboxes: [{center: [0, 0, 0]}]\n", "boxes[0]", "needs both"),
    ("terrain: boxes\nboxes: [{center: [0, 0], size: [1, 1, 1]}]\n", "boxes[0].center",
     "list of 3"),
    ("terrain: boxes\nboxes: [{center: [0, 0, 0], size: [1, 0, 1]}]\n", "boxes[0].size[1]",
     "must be > 0"),
    ("terrain: blocks\nparams: {size_min: 0.9, size_max: 0.3}\n", "params.size_min", "above"),
    ("- just\n- a list\n", "terrain", "mapping"),
    ("terrain: [unclosed\n", "terrain", "not valid YAML"),
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
    with pytest.raises(ConfigError, match="cannot read"):
        load_terrain(tmp_path / "nope.yaml")


@pytest.mark.parametrize("text, key", [
    ("watchdog_ms: 0\n", "watchdog_ms"),
    ("holder: {release_on: later}\n", "holder.release_on"),
    ("holder: {timeconst_s: -1}\n", "holder.timeconst_s"),
    ("camera: {decimation: 0}\n", "camera.decimation"),
    ("camera: {mount_pos_m: [0, 0]}\n", "camera.mount_pos_m"),
    ("camera: {min_range_m: 7.0}\n", "camera.min_range_m"),
    ("camera: {fov: 90}\n", "camera.fov"),
    ("lockstep: {timeout_s: 0}\n", "lockstep.timeout_s"),
    ("physics: {pelvis_height_m: 2.0}\n", "physics.pelvis_height_m"),
])
def test_bad_sim_gains_name_file_and_key(tmp_path: Path, text: str, key: str) -> None:
    f = tmp_path / "sim.yaml"
    f.write_text(text)
    with pytest.raises(ConfigError) as info:
        load_gains(f)
    assert info.value.key == key and info.value.file == str(f)


def test_shipped_gains_load() -> None:
    s = load_gains(HW_CONFIG / "gains" / "sim.yaml")
    assert s.sim.watchdog_s == 0.010 and s.camera.out_width == 106 and s.camera.out_height == 60
