"""S3 built from a profile: an unknown key or a bad value, in its params or in its gains file
(Table VIII), stops the build with a ConfigError naming the file, the dotted key and what is
allowed."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
import yaml

from processes.s3.params import S3Params
from processes.s3.process import Params
from runtime.builder import build_node, process_module, read_config
from runtime.config import HW_CONFIG_DIR, load_profile
from runtime.errors import ConfigError
from runtime.params import load

PROFILE = """\
include: [{hw}/hosts.yaml, {hw}/channels.yaml]
mode: lockstep
processes:
  s3:
    host: laptop
    module: processes.s3.process
    inputs: {{elevation_map: elevation_map}}
    outputs: {{footholds: footholds}}
    gains: {gains}
    params: {params}
launch: [s3]
"""


def _proc(tmp_path: Path, params: dict[str, Any], gains: Any = None):  # type: ignore[no-untyped-def]
    """The profile's s3, with a copy of hw_config/gains/s3.yaml changed by ``gains``."""
    doc = yaml.safe_load((HW_CONFIG_DIR / "gains" / "s3.yaml").read_text())
    if gains is not None:
        gains(doc)
    gfile = tmp_path / "s3.yaml"
    gfile.write_text(yaml.safe_dump(doc, sort_keys=False))
    pfile = tmp_path / "profile.yaml"
    pfile.write_text(PROFILE.format(hw=HW_CONFIG_DIR, gains=gfile, params=params))
    profile = load_profile(pfile)
    return profile.processes["s3"], profile, pfile, gfile


def test_the_profile_as_written_builds_in_its_variant(tmp_path: Path) -> None:
    proc, profile, _, _ = _proc(tmp_path, {"variant": "hardware"})
    params, gains = read_config(proc, process_module(proc))
    assert params == Params(variant="hardware")
    assert gains == load(S3Params, HW_CONFIG_DIR / "gains" / "s3.yaml", "hardware")
    assert (gains.k_hyst, gains.inpainting) == (0.6, "ns")  # Table VIII, hardware
    assert build_node(proc, profile).pipeline.params == gains


def test_a_bad_param_names_the_profile_the_key_and_what_is_allowed(tmp_path: Path) -> None:
    proc, profile, pfile, _ = _proc(tmp_path, {"varient": "hardware"})
    with pytest.raises(ConfigError) as err:
        build_node(proc, profile)
    assert (err.value.file, err.value.key) == (str(pfile), "processes.s3.params.varient")
    assert err.value.problem == "unknown key" and err.value.allowed == "variant"
    proc, profile, pfile, _ = _proc(tmp_path, {"variant": 2})
    with pytest.raises(ConfigError) as err:
        build_node(proc, profile)
    assert (err.value.file, err.value.key) == (str(pfile), "processes.s3.params.variant")
    assert "must be a string" in err.value.problem


def test_a_variant_the_gains_file_lacks_names_the_file_and_its_variants(tmp_path: Path) -> None:
    proc, profile, _, gfile = _proc(tmp_path, {"variant": "lab"})
    with pytest.raises(ConfigError) as err:
        build_node(proc, profile)
    assert (err.value.file, err.value.key) == (str(gfile), "variants")
    assert err.value.problem == "no variant 'lab'"
    assert err.value.allowed == "simulation, hardware"


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
    proc, profile, _, gfile = _proc(tmp_path, {"variant": variant}, change)
    with pytest.raises(ConfigError) as err:
        build_node(proc, profile)
    assert (err.value.file, err.value.key) == (str(gfile), key)
    assert problem in err.value.problem
    if allowed is None:  # an unknown key: every field of the gains, alphabetically
        assert err.value.allowed is not None and "k_safe, log_sigma_px" in err.value.allowed
    else:
        assert err.value.allowed == allowed
