"""The sim built from a profile (``runtime.builder.build_node``): an unknown or bad param, and
an unknown or bad key of its gains file (a range, a cross-field check), are ConfigErrors
naming the file, the dotted key and what is allowed."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.conftest import build_one, config_error


def test_params_and_gains_reach_the_node(tmp_path: Path) -> None:
    node = build_one(tmp_path, "sim",
                     params={"terrain": "stones", "terrain_seed": 3, "camera_render": False,
                             "holder_release": "manual",
                             "push": {"after_release_s": 6, "force_n": [0, 400, 0]}},
                     gains=lambda g: g["lockstep"].__setitem__("timeout_s", 0.02))
    try:
        s = node.settings
        assert s.terrain.seed == 3 and node.render_mode == "off"
        assert s.sim.holder.release_on == "manual" and s.sim.push.force_n == (0.0, 400.0, 0.0)
        assert s.lockstep_timeout_s == 0.02 and s.lockstep_min_timeout_s == 0.001
    finally:
        node.close()


@pytest.mark.parametrize(("params", "message"), [
    ({"terrian": "flat"}, "params.terrian: unknown key (allowed: camera_render, drive, "
                          "drops, holder_release, publish_footholds, push, terrain, terrain_seed, "
                          "variant)"),
    ({"drive": "fast"}, "params.drive: 'fast' is not one of the allowed values "
                        "(allowed: auto, periodic, command)"),
    ({"camera_render": "never"}, "params.camera_render: 'never' is not one of the allowed "
                                 "values (allowed: auto, process, thread, inline, off)"),
    ({"camera_render": 0}, "params.camera_render: 0 is not one of the allowed values"),
    ({"terrain_seed": -1}, "params.terrain_seed: out of range: -1 (allowed: [0, inf])"),
    ({"terrain": "beam", "terrain_seed": 2}, "params.terrain_seed: terrain 'beam' is not "
                                             "random (allowed: stones, blocks)"),
    ({"terrain": "lava"}, "params.terrain: unknown terrain 'lava' (allowed: flat, stairs, "
                          "beam, stones, blocks, ramped_stones, winding_beam or a .yaml file)"),
    ({"push": {"after_release_s": 1.0, "force_n": [0, 0]}},
     "params.push.force_n: must be a list of 3, got 2"),
    ({"holder_release": "later"}, "params.holder_release: 'later' is not one of the allowed "
                                  "values (allowed: first_command, first_nonzero_command, "
                                  "manual)"),
])
def test_a_bad_param_names_the_profile_key_and_allowed(tmp_path: Path, params, message) -> None:
    err = config_error(tmp_path, "sim", params=params)
    assert str(err).startswith(f"{tmp_path / 'one.yaml'}: processes.sim.{message}")


CAMERA_KEYS = ("allowed: cx, cy, decimation, depth_scale, dropout, enabled, fx, fy, height, "
               "max_range_m, min_range_m, noise_std_at_1m, rate_hz, render, see_robot, seed, "
               "width")


@pytest.mark.parametrize(("change", "message"), [
    (lambda g: g["camera"].__setitem__("fov", 90), f"camera.fov: unknown key ({CAMERA_KEYS})"),
    # the camera's mount is the robot's (runtime.robot), not a gain
    (lambda g: g["camera"].__setitem__("pitch_down_deg", 50.0),
     f"camera.pitch_down_deg: unknown key ({CAMERA_KEYS})"),
    (lambda g: g["holder"].__setitem__("timeconst_s", 2.0),
     "holder.timeconst_s: out of range: 2.0 (allowed: [0.001, 1.0] s)"),
    (lambda g: g["camera"].__setitem__("min_range_m", 7.0),
     "camera.min_range_m: 7.0 is not below max_range_m (6.0) (allowed: [0.0, 6.0) m)"),
    (lambda g: g["lockstep"].__setitem__("min_timeout_s", 0.5),
     "lockstep.min_timeout_s: 0.5 is above timeout_s (0.01) (allowed: [0.0001, 0.01] s)"),
    (lambda g: g.__setitem__("watchdog_ms", "10"),
     "watchdog_ms: must be a number, got '10' (allowed: [0.5, 1000.0] ms)"),
])
def test_a_bad_gains_file_names_file_key_and_allowed(tmp_path: Path, change, message) -> None:
    err = config_error(tmp_path, "sim", gains=change)
    assert str(err) == f"{tmp_path / 'gains.yaml'}: {message}"
