"""Each host's local channels on a bus of its own, the crossing ones on the network bus:
a process hears only its host and the network, and a profile that would leave a subscriber
deaf fails to load."""

from __future__ import annotations

import time
from pathlib import Path

import pytest

from lcmtypes import command_t
from runtime.bus import Bus
from runtime.config import HW_CONFIG_DIR, load_profile
from runtime.errors import ConfigError
from tests.conftest import wait_for

HOSTS = f"{HW_CONFIG_DIR / 'hosts.yaml'}"


def _profile(tmp_path: Path, body: str, hosts: str = HOSTS) -> Path:
    p = tmp_path / "p.yaml"
    p.write_text(f"include: [{hosts}]\n" + body)
    return p


TWO_HOSTS = """
channels:
  local: NUC_ONLY
  shared: NETWORK_SHARED
  tools: {name: TOOLS, scope: network}
  cam: {name: CAM, scope: laptop}
processes:
  a: {host: nuc, module: tests.procs.ticker, rate_hz: 10, outputs: {out: local, x: shared}}
  b: {host: nuc, module: tests.procs.echo, inputs: {in: local}, outputs: {out: tools}}
  c: {host: laptop, module: tests.procs.echo, inputs: {in: shared}, outputs: {out: cam}}
launch: [a, b, c]
"""


def test_each_channel_lives_on_its_hosts_bus_or_the_network(tmp_path, lcm_url):
    prof = load_profile(_profile(tmp_path, TWO_HOSTS))
    port = int(lcm_url.rsplit(":", 1)[1])
    assert prof.domains["network"] == lcm_url
    assert prof.domains["nuc"].endswith(f":{port + 2}")  # hosts.yaml: lcm_port_offset 2
    assert prof.channel_domains == {"NUC_ONLY": "nuc", "NETWORK_SHARED": "network",
                                    "TOOLS": "network", "CAM": "laptop"}


def test_a_subscriber_on_another_host_than_a_local_channel_is_a_config_error(tmp_path):
    body = TWO_HOSTS.replace("c: {host: laptop, module: tests.procs.echo, inputs: {in: shared}",
                             "c: {host: laptop, module: tests.procs.echo, inputs: {in: local}")
    with pytest.raises(ConfigError) as err:
        load_profile(_profile(tmp_path, body))
    assert err.value.key == "processes.c.inputs.in"
    assert "NUC_ONLY stays on host nuc" in str(err.value)
    assert "NETWORK_" in str(err.value)  # ...and it says how to make it cross


def test_a_local_channel_published_from_two_hosts_is_a_config_error(tmp_path):
    body = TWO_HOSTS.replace("outputs: {out: cam}", "outputs: {out: local}")
    with pytest.raises(ConfigError, match="NUC_ONLY is local to one host"):
        load_profile(_profile(tmp_path, body))


def test_an_unknown_scope_names_the_hosts_allowed(tmp_path):
    body = TWO_HOSTS.replace("scope: laptop", "scope: moon")
    with pytest.raises(ConfigError, match="allowed: network, host, laptop, nuc, target_pc"):
        load_profile(_profile(tmp_path, body))


def test_shared_host_buses_put_every_channel_on_one_url(tmp_path, lcm_url):
    hosts = tmp_path / "hosts.yaml"
    hosts.write_text(Path(HOSTS).read_text().replace("host_buses: ports", "host_buses: shared"))
    prof = load_profile(_profile(tmp_path, TWO_HOSTS, hosts=str(hosts)))
    assert set(prof.domains.values()) == {lcm_url}


def test_the_laptop_never_hears_the_nucs_local_traffic(tmp_path, lcm_url):
    prof = load_profile(_profile(tmp_path, TWO_HOSTS))
    nuc = Bus.for_profile(prof, source="nuc-side")
    laptop = Bus.for_profile(prof, source="laptop-side")
    # the laptop listens on everything of its own bus and the network, by regex
    heard: list[str] = []
    laptop.subscribe_raw(".*", lambda c, d: heard.append(c),
                         urls=[prof.domains["laptop"], prof.domains["network"]])
    local = nuc.subscribe("NUC_ONLY", command_t)
    time.sleep(0.1)
    for _ in range(5):
        nuc.publish("NUC_ONLY", command_t())
        nuc.publish("NETWORK_SHARED", command_t())
    wait_for(lambda: local.received >= 5 and heard.count("NETWORK_SHARED") >= 5, 5,
             poll=lambda: (nuc.drain(0.02), laptop.drain(0.02)), what="both buses")
    assert "NUC_ONLY" not in heard


def test_a_bus_that_only_publishes_joins_no_domain(tmp_path):
    prof = load_profile(_profile(tmp_path, TWO_HOSTS))
    bus = Bus.for_profile(prof)
    bus.publish("NUC_ONLY", command_t())
    assert bus.filenos() == []
