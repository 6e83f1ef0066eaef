"""``cassie launch PROFILE key:=value``: a gain, a param, a process key and the mode changed
from the command line reach the processes as built, through a profile written into the
launch's log folder; a key that is not there is a clear error before anything starts."""

from __future__ import annotations

import importlib
import subprocess
import sys
from pathlib import Path

import pytest

from runtime.builder import build_node
from runtime.config import HW_CONFIG_DIR, load_profile
from runtime.errors import ConfigError
from tests.conftest import REPO
from tools.overrides import write_overlay


def test_a_gain_a_param_a_process_key_and_the_mode_reach_the_built_processes(
        tmp_path: Path) -> None:
    out = write_overlay(HW_CONFIG_DIR / "sim.yaml",
                        ["mode:=lockstep", "osc.gains.walking.swing_clearance:=0.12",
                         "torque_bridge.params.release_after_s:=2.5", "osc.nice:=-5"], tmp_path)
    profile = load_profile(out)
    assert profile.mode == "lockstep"
    osc = profile.processes["osc"]
    assert osc.nice == -5
    assert build_node(osc, profile).params.walking.swing_clearance == pytest.approx(0.12)
    assert profile.processes["torque_bridge"].params["release_after_s"] == 2.5
    # the rest as in the profile, and the profile itself untouched
    base = load_profile(HW_CONFIG_DIR / "sim.yaml")
    assert build_node(base.processes["osc"], base).params.walking.swing_clearance == 0.15
    assert profile.launch == base.launch


@pytest.mark.parametrize(("item", "says"), [
    ("osc.gains.walking.swing_clearence:=0.1", "no such gain"),
    ("nosuch.params.x:=1", "is no process of profile sim"),
    ("mode:=sideways", "not one of the allowed values"),
    ("osc.rate_hz:=fast", "must be a number"),
    ("osc=1", "not an override"),
])
def test_a_bad_override_is_a_clear_error(item: str, says: str, tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match=says):
        write_overlay(HW_CONFIG_DIR / "sim.yaml", [item], tmp_path)


def test_the_launch_command_reports_a_bad_override_before_it_starts(tmp_path: Path) -> None:
    done = subprocess.run([sys.executable, "-m", "tools.cli", "launch", "sim",
                           "osc.gains.walking.nope:=1", "--log-dir", str(tmp_path)],
                          capture_output=True, text=True, cwd=REPO, timeout=60)
    assert done.returncode == 2, done.stdout + done.stderr
    assert "walking.nope: no such gain" in done.stderr


def test_a_gain_a_variant_sets_is_overridden_in_the_variant_that_runs(tmp_path: Path) -> None:
    """The MPFC's gains file has the paper's two columns as variants; its simulation variant
    sets the step width itself, so the override must reach it there, not only the top."""
    from runtime.params import load

    base = load_profile(HW_CONFIG_DIR / "sim.yaml")
    mpfc = base.processes["mpfc"]
    variant = mpfc.params.get("variant", "simulation")
    out = write_overlay(HW_CONFIG_DIR / "sim.yaml", ["mpfc.gains.step_width_m:=0.17"],
                        tmp_path)
    profile = load_profile(out)
    gains_cls = importlib.import_module(mpfc.module).Gains
    assert load(gains_cls, mpfc.gains_file, variant).step_width_m == 0.15  # (as written)
    assert load(gains_cls, profile.processes["mpfc"].gains_file, variant).step_width_m == 0.17


@pytest.mark.parametrize(("item", "key", "allowed"), [
    ("osc.params.start:=run", "osc.params.start", "walk, stand"),
    ("osc.gains.walking.toe.kp:=-1", "osc.gains.walking.toe.kp", "[0.0, inf]"),
    ("mpfc.gains.step_width_m:=-1", "mpfc.gains.step_width_m", "[0.0, inf] m"),  # (a variant's)
    ("osc.nice:=99", "osc.nice", "[-20, 19]"),
    ("mode:=sideways", "mode", "realtime, lockstep"),
])
def test_a_bad_value_typed_on_the_command_line_is_blamed_on_it(
        item: str, key: str, allowed: str, tmp_path: Path) -> None:
    """Not on hw_config/processes.yaml, nor on the files written from the command line."""
    with pytest.raises(ConfigError) as err:
        write_overlay(HW_CONFIG_DIR / "sim.yaml", [item], tmp_path)
    assert (err.value.file, err.value.key, err.value.allowed) == ("the command line", key,
                                                                  allowed)
    assert str(err.value).startswith(f"the command line: {key}: ")
