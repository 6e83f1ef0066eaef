"""A bad value that a profile's ``overrides:`` wrote is blamed on that profile, at the
override's key (``overrides.PROCESS.KEY``), not on the catalog entry it replaced in
hw_config/processes.yaml: in the profile's own checks and in a process's params as its build
reads them, through includes (the last file to write the key is named); a value that no
override wrote is still the catalog's."""

from __future__ import annotations

from pathlib import Path

import pytest

from runtime.builder import build_node, process_module, read_config
from runtime.config import HW_CONFIG_DIR, load_profile
from runtime.errors import ConfigError

SIM = HW_CONFIG_DIR / "sim.yaml"
LAUNCH = "launch: [sim, state_estimator, torque_bridge, osc, mpfc]\n"


def _profile(folder: Path, name: str, body: str, include: Path = SIM) -> Path:
    """A profile in ``folder`` that includes ``include`` and says ``body``."""
    path = folder / f"{name}.yaml"
    path.write_text(f"include: [{include}]\n{LAUNCH}{body}")
    return path


def _params_error(path: Path, process: str) -> ConfigError:
    """The ConfigError of reading ``process``'s params and gains in profile ``path``."""
    proc = load_profile(path).processes[process]
    with pytest.raises(ConfigError) as err:
        read_config(proc, process_module(proc))
    return err.value


def test_a_bad_param_override_names_the_profile_and_the_override_key(tmp_path: Path) -> None:
    path = _profile(tmp_path, "mine", "overrides: {osc: {params: {start: run}}}\n")
    err = _params_error(path, "osc")
    assert (err.file, err.key, err.allowed) == (str(path), "overrides.osc.params.start",
                                                "walk, stand")
    assert str(err).startswith(f"{path}: overrides.osc.params.start: 'run' is not one of")
    profile = load_profile(path)  # the node's build says the same (cassie check, cassie run)
    with pytest.raises(ConfigError, match=r"mine\.yaml: overrides\.osc\.params\.start: "):
        build_node(profile.processes["osc"], profile)


def test_a_mapping_an_override_wrote_whole_is_blamed_on_it(tmp_path: Path) -> None:
    """The catalog's sim has no push: one written without its required start time is the
    override's."""
    path = _profile(tmp_path, "shove", "overrides: {sim: {params: {push: {force_n: [1, 2, 3]}}}}\n")
    err = _params_error(path, "sim")
    assert (err.file, err.key) == (str(path), "overrides.sim.params.push.after_release_s")
    assert err.problem == "is required"


def test_the_last_profile_to_write_a_key_is_the_one_named(tmp_path: Path) -> None:
    mid = _profile(tmp_path, "mid", "overrides: {torque_bridge: {params: {fill_hz: -1}}}\n")
    top = _profile(tmp_path, "top", "", include=mid)
    err = _params_error(top, "torque_bridge")  # written in the included file: named there
    assert (err.file, err.key) == (str(mid), "overrides.torque_bridge.params.fill_hz")
    assert err.allowed and "(0.0, 2000.0]" in err.allowed
    again = _profile(tmp_path, "again", "overrides: {torque_bridge: {params: {fill_hz: 0}}}\n",
                     include=mid)
    err = _params_error(again, "torque_bridge")
    assert (err.file, err.key) == (str(again), "overrides.torque_bridge.params.fill_hz")


def test_a_profile_check_of_an_overridden_key_names_the_profile(tmp_path: Path) -> None:
    path = _profile(tmp_path, "slow", "overrides: {osc: {max_rate_hz: 0}}\n")
    with pytest.raises(ConfigError) as err:
        load_profile(path)
    assert (err.value.file, err.value.key) == (str(path), "overrides.osc.max_rate_hz")
    assert err.value.allowed == "(0.0, 100000.0] Hz"


def test_a_value_no_override_wrote_is_still_the_catalogs(tmp_path: Path) -> None:
    path = _profile(tmp_path, "mine", "overrides: {osc: {params: {start: stand}}}\n")
    proc = load_profile(path).processes["osc"]
    catalog = str(HW_CONFIG_DIR / "processes.yaml")
    assert str(proc.source_file) == catalog

    def named(key: str) -> tuple[str, str]:
        err = proc.blame(ConfigError(catalog, f"processes.osc.{key}", "bad"))
        return err.file, err.key

    assert named("deadline_ms") == (catalog, "processes.osc.deadline_ms")  # no one overrode it
    assert named("params.start") == (str(path), "overrides.osc.params.start")
    assert named("params.stand_first_s") == (str(SIM), "overrides.osc.params.stand_first_s")
