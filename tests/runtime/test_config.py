"""hw_config is validated at load time; every error names the file, the key and what is allowed."""

from __future__ import annotations

from pathlib import Path

import pytest

from runtime.config import HW_CONFIG_DIR, check_depends, load_profile
from runtime.errors import ConfigError
from tests.conftest import PROFILES

BASE = PROFILES / "runtime.yaml"


def _profile(tmp_path: Path, body: str) -> Path:
    p = tmp_path / "bad.yaml"
    p.write_text(f"include: [{BASE}]\nlaunch: [ticker]\n" + body)
    return p


@pytest.mark.parametrize(
    ("body", "key", "fragment"),
    [
        ("overrides: {ticker: {rate_hz: fast}}", "overrides.ticker.rate_hz", "must be a number"),
        ("overrides: {ticker: {rate_hz: -5}}", "overrides.ticker.rate_hz", "out of range"),
        ("overrides: {ticker: {host: moon}}", "overrides.ticker.host", "allowed: nuc"),
        (
            "overrides: {ticker: {restart: {policy: sometimes}}}",
            "overrides.ticker.restart.policy",
            "allowed: always, on-failure, never",
        ),
        (
            "overrides: {ticker: {outputs: {out: NOPE}}}",
            "overrides.ticker.outputs.out",
            "unknown channel",
        ),
        (
            "overrides: {ticker: {cpu_affinity: [a]}}",
            "overrides.ticker.cpu_affinity[0]",
            "must be an integer, got 'a' (allowed: [0, inf])",
        ),
        ("overrides: {ticker: {cpu_affinity: []}}", "overrides.ticker.cpu_affinity",
         "list of CPU numbers"),
        ("overrides: {ticker: {nice: 99}}", "overrides.ticker.nice", "allowed: [-20, 19]"),
        ("overrides: {ticker: {colour: red}}", "overrides.ticker.colour", "unknown key"),
        ("mode: turbo", "mode", "allowed: realtime, lockstep"),
        ("overrides: {ghost: {rate_hz: 1}}", "overrides.ghost", "no such process"),
    ],
)
def test_bad_value_fails_with_message_naming_file_and_key(tmp_path, body, key, fragment):
    path = _profile(tmp_path, body)
    with pytest.raises(ConfigError) as err:
        load_profile(path)
    text = str(err.value)
    assert err.value.key == key
    assert text.startswith(f"{path}: {key}: ")  # the value was written in the profile
    assert key in text and fragment in text


def test_error_in_an_included_file_names_that_file(tmp_path):
    inc = tmp_path / "procs.yaml"
    inc.write_text("processes:\n  extra: {host: nuc, module: tests.procs.ticker, rate_hz: zero}\n")
    p = tmp_path / "top.yaml"
    p.write_text(f"include: [{BASE}, procs.yaml]\nlaunch: [extra]\n")
    with pytest.raises(ConfigError) as err:
        load_profile(p)
    assert err.value.file == str(inc)
    assert err.value.key == "processes.extra.rate_hz"


def test_unknown_launch_entry_lists_allowed_processes(tmp_path):
    p = tmp_path / "x.yaml"
    p.write_text(f"include: [{BASE}]\nlaunch: [tickr]\n")
    with pytest.raises(
        ConfigError, match=r"launch\[0\]: no process named 'tickr'.*allowed: .*ticker"
    ):
        load_profile(p)


def test_dependency_cycle_is_reported(tmp_path):
    p = tmp_path / "x.yaml"
    p.write_text(
        f"include: [{BASE}]\nlaunch: [ticker, echo]\n"
        "overrides: {ticker: {depends_on: [echo]}}\n"
    )
    with pytest.raises(ConfigError, match="dependency cycle"):
        check_depends(load_profile(p))


def test_good_profile_loads_with_channels_ttl_and_dependency_order():
    prof = load_profile(BASE)
    echo = prof.processes["echo"]
    assert echo.inputs["in"].name == "TEST_TICK"
    assert echo.depends_on == ("ticker",)
    assert check_depends(prof) == ["ticker", "echo"]
    assert prof.channels["tick"].ttl == 0


def test_product_config_files_are_valid():
    from runtime.config import _channel, load_yaml

    chans = load_yaml(HW_CONFIG_DIR / "channels.yaml")["channels"]
    parsed = {k: _channel(k, v, HW_CONFIG_DIR / "channels.yaml") for k, v in chans.items()}
    assert parsed["network_state"].ttl == 1 and parsed["state"].ttl == 0
    assert parsed["robot_output"].udp == ("nuc", 25000)  # (a host: its address, below)
    sim = load_profile(HW_CONFIG_DIR / "sim.yaml")
    assert sim.channels["robot_output"].udp == (sim.hosts["nuc"].address, 25000)
    assert sim.channels["robot_input"].udp == (sim.hosts["target_pc"].address, 25001)
    for profile in HW_CONFIG_DIR.glob("*.yaml"):
        if "launch" in load_yaml(profile):
            prof = load_profile(profile)
            assert prof.launch


def test_a_file_included_twice_is_fine_but_a_cycle_is_reported(tmp_path):
    (tmp_path / "a.yaml").write_text(f"include: [{BASE}]\n")
    (tmp_path / "b.yaml").write_text(f"include: [{BASE}, a.yaml]\nlaunch: [ticker]\n")
    assert load_profile(tmp_path / "b.yaml").launch == ("ticker",)
    (tmp_path / "c.yaml").write_text("include: [d.yaml]\n")
    (tmp_path / "d.yaml").write_text("include: [c.yaml]\nlaunch: [ticker]\n")
    with pytest.raises(ConfigError, match=r"cycle: d.yaml -> c.yaml -> d.yaml"):
        load_profile(tmp_path / "d.yaml")


def test_profile_by_name_is_found_in_hw_config_not_a_same_named_folder(monkeypatch):
    from runtime.config import find_profile
    from tests.conftest import REPO

    monkeypatch.chdir(REPO)  # where the sim/ package folder is also called "sim"
    assert find_profile("sim") == (HW_CONFIG_DIR / "sim.yaml").resolve()
    assert load_profile("sim").name == "sim"


def test_a_key_written_twice_is_an_error_naming_the_file_and_line(tmp_path):
    """PyYAML keeps the last of two equal keys silently; hw_config files must not."""
    from processes.osc.tasks import OscGains
    from runtime.config import load_yaml
    from runtime.params import load

    f = tmp_path / "gains.yaml"
    f.write_text("qp:\n  w: 1\nsafety:\n  fall_height: 0.6\n  fall_height: 0.2\n")
    with pytest.raises(ConfigError) as e:
        load_yaml(f)
    with pytest.raises(ConfigError, match="twice"):  # a process's own gains reader too
        load(OscGains, f)
    assert "gains.yaml" in str(e.value)
    assert "'fall_height' twice (first on line 4)" in str(e.value)


def test_two_input_roles_on_one_channel_are_refused_at_load(tmp_path):
    profile = tmp_path / "two_roles.yaml"
    profile.write_text(f"include: [{HW_CONFIG_DIR / 'sim.yaml'}]\nprofile: two_roles\n"
                       "launch: [sim, state_estimator, torque_bridge, osc, mpfc]\n"
                       "overrides: {osc: {inputs: {plan: state}}}\n")
    with pytest.raises(ConfigError, match=r"two_roles.yaml: overrides\.osc\.inputs\.plan: "
                       r"channel CASSIE_STATE is already its input"):
        load_profile(profile)


def test_a_udp_link_names_a_host_or_an_address(tmp_path):
    from runtime.config import _channel
    from runtime.config_types import HostConfig
    from runtime.errors import ConfigError

    hosts = {"nuc": HostConfig("nuc", "10.1.2.3")}
    f = tmp_path / "channels.yaml"
    assert _channel("x", {"udp": "nuc:25000"}, f, hosts).udp == ("10.1.2.3", 25000)
    assert _channel("x", {"udp": "10.0.0.9:25000"}, f, hosts).udp == ("10.0.0.9", 25000)
    with pytest.raises(ConfigError, match=r"channels.x.udp.*'laptp' is neither a host.*nuc"):
        _channel("x", {"udp": "laptp:25000"}, f, hosts)
