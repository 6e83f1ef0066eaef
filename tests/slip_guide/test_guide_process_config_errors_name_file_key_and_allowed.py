"""The SLIP guide process and the MPFC's guide params built from a profile: a bad value stops
the build with a ConfigError naming the file, the dotted key and what is allowed."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from processes.slip_guide.process import Params
from runtime.builder import process_module, read_config
from tests.conftest import assert_names, config_error, one_process


def test_the_profile_as_written_reads_the_guide_variant(tmp_path: Path) -> None:
    proc, _ = one_process(tmp_path, "slip_guide", mode="lockstep")
    params, gains = read_config(proc, process_module(proc))
    assert params == Params()
    assert gains.horizon_s == 3.0 and gains.dt_s == 0.15  # the variant over Table I's file


@pytest.mark.parametrize(("params", "key", "problem", "allowed"), [
    ({"varaint": "guide"}, "varaint", "unknown key",
     "corridor_m, default_velocity, line_return_s, relay_turn_deg, variant, "
     "velocity_window_s"),
    ({"variant": "long"}, "variant", "'long' is not one of the allowed values",
     "guide, table1"),
    ({"velocity_window_s": 0.0}, "velocity_window_s", "out of range: 0.0", "(0.0, 20.0] s"),
])
def test_a_bad_guide_param_names_the_profile_the_key_and_what_is_allowed(
        tmp_path: Path, params: dict[str, Any], key: str, problem: str, allowed: str) -> None:
    err = config_error(tmp_path, "slip_guide", params, mode="lockstep")
    assert_names(err, tmp_path / "one.yaml", f"processes.slip_guide.params.{key}", problem,
                 allowed)


def test_a_bad_variant_of_the_gains_file_names_it(tmp_path: Path) -> None:
    def change(doc: dict[str, Any]) -> None:
        doc["variants"]["guide"]["horizon_s"] = 0.2

    err = config_error(tmp_path, "slip_guide", {"variant": "guide"}, change, mode="lockstep")
    assert_names(err, tmp_path / "gains.yaml", "variants.guide.horizon_s",
                 "fewer than two samples", ">= 0.3 s")


@pytest.mark.parametrize(("params", "key", "problem", "allowed"), [
    ({"guide": "yes"}, "guide", "must be true or false", "true, false"),
    ({"guide_max_age_s": 0.0}, "guide_max_age_s", "out of range: 0.0", "(0.0, 10.0] s"),
    ({"guide_margin_m": -0.1}, "guide_margin_m", "out of range: -0.1", "[0.0, 2.0] m"),
])
def test_a_bad_mpfc_guide_param_names_the_profile_the_key_and_what_is_allowed(
        tmp_path: Path, params: dict[str, Any], key: str, problem: str, allowed: str) -> None:
    err = config_error(tmp_path, "mpfc", params, mode="lockstep")
    assert_names(err, tmp_path / "one.yaml", f"processes.mpfc.params.{key}", problem, allowed)


def test_the_mpfc_guided_without_a_guide_input_says_what_it_needs(tmp_path: Path) -> None:
    import yaml

    from runtime.builder import build_node
    from runtime.config import load_profile
    from runtime.errors import ConfigError
    from tests.conftest import one_process_profile

    path = one_process_profile(tmp_path, "mpfc", {"guide": True}, mode="lockstep")
    doc = yaml.safe_load(path.read_text())
    del doc["processes"]["mpfc"]["inputs"]["guide"]
    path.write_text(yaml.safe_dump(doc))
    profile = load_profile(path)
    with pytest.raises(ConfigError) as err:
        build_node(profile.processes["mpfc"], profile)
    assert_names(err.value, path, "processes.mpfc.params.guide",
                 "true, but the process has no guide input",
                 "false, or inputs: {guide: guide_plan} (the SLIP guide's plan, "
                 "processes.slip_guide.process)")
