"""The MPFC built from a profile: an unknown key or a bad value, in its params or in its gains
file, stops the build with a ConfigError naming the file, the dotted key and what is allowed."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from processes.mpfc.process import Params
from runtime.builder import process_module, read_config
from runtime.config import HW_CONFIG_DIR
from runtime.params import load
from tests.conftest import assert_names, config_error, one_process


def test_the_profile_as_written_reads_its_params_and_gains(tmp_path: Path) -> None:
    proc, _ = one_process(tmp_path, "mpfc", {"variant": "hardware", "footholds": "flat"},
                          mode="lockstep")
    params, gains = read_config(proc, process_module(proc))
    assert params == Params(variant="hardware", footholds="flat")
    assert gains == load(type(gains), HW_CONFIG_DIR / "gains" / "mpfc.yaml", "hardware")


ALL_PARAMS = ("dcm_gains, dcm_variant, default_velocity, foothold_max_height_m, footholds, "
              "guide, guide_long_step_m, guide_margin_m, guide_max_age_s, guide_max_speed_mps, "
              "height_lookup, planner, variant")


@pytest.mark.parametrize(("params", "key", "problem", "allowed"), [
    ({"foothold_sorce": "flat"}, "foothold_sorce", "unknown key", ALL_PARAMS),
    ({"variant": "moon"}, "variant", "'moon' is not one of the allowed values",
     "hardware, simulation"),
    ({"footholds": "lidar"}, "footholds", "'lidar' is not one of the allowed values",
     "channel, flat"),
    ({"foothold_max_height_m": -0.1}, "foothold_max_height_m", "out of range: -0.1",
     "[0.0, inf] m"),
    ({"height_lookup": "yes"}, "height_lookup", "must be true or false", "true, false"),
])
def test_a_bad_param_names_the_profile_the_key_and_what_is_allowed(
        tmp_path: Path, params: dict[str, Any], key: str, problem: str, allowed: str) -> None:
    err = config_error(tmp_path, "mpfc", params, mode="lockstep")
    assert_names(err, tmp_path / "one.yaml", f"processes.mpfc.params.{key}", problem, allowed)


@pytest.mark.parametrize(("variant", "change", "key", "problem", "allowed"), [
    ("simulation", lambda d: d.update(horizon=3), "horizon", "unknown key", None),
    ("simulation", lambda d: d["variants"]["simulation"].update(step_width_m=-0.15),
     "variants.simulation.step_width_m", "out of range: -0.15", "[0.0, inf] m"),
    ("hardware", lambda d: d.update(search="guess"), "search",
     "'guess' is not one of the allowed values", "auto, enumerate, branch_and_bound"),
    ("hardware", lambda d: d.update(t_ss_min_s=0.31), "t_ss_min_s",
     "need 0 < t_ss_min_s <= t_ss_s <= t_ss_max_s", "0 < min <= nominal <= max"),
    ("simulation", lambda d: d["variants"].pop("simulation"), "variants",
     "no variant 'simulation'", "hardware"),
])
def test_a_bad_gain_names_the_gains_file_the_key_and_what_is_allowed(
        tmp_path: Path, variant: str, change: Any, key: str, problem: str,
        allowed: str | None) -> None:
    err = config_error(tmp_path, "mpfc", {"variant": variant}, change, mode="lockstep")
    assert_names(err, tmp_path / "gains.yaml", key, problem, allowed, listing="horizon_steps")
