"""Both processes build through the hw_config loader, as `cassie run` / `cassie launch` do."""

from __future__ import annotations

from pathlib import Path

import pytest

from runtime.builder import build_node
from runtime.config import HW_CONFIG_DIR, load_profile
from runtime.errors import ConfigError

PROFILE = """
profile: nuc_io_test
include: [{hw}/hosts.yaml, {hw}/channels.yaml]
mode: realtime
processes:
  state_estimator:
    host: nuc
    module: processes.state_estimator.process
    rate_hz: 2000
    deadline_ms: 0.5
    inputs: {{robot_output: robot_output}}
    outputs: {{state: state, network_state: network_state, contact: contact}}
    gains: {hw}/gains/state_estimator.yaml
  torque_bridge:
    host: nuc
    module: processes.torque_bridge.process
    rate_hz: 2000
    deadline_ms: 0.5
    inputs: {{torque: torque, state: state}}
    outputs: {{robot_input: robot_input, applied_input: applied_input}}
    gains: {hw}/gains/torque_bridge.yaml
    depends_on: [state_estimator]
launch: [state_estimator, torque_bridge]
"""


def _profile(tmp_path: Path, extra: str = "") -> Path:
    f = tmp_path / "nuc.yaml"
    f.write_text(PROFILE.format(hw=HW_CONFIG_DIR) + extra)
    return f


def test_estimator_and_bridge_build_from_hw_config(tmp_path: Path):
    prof = load_profile(str(_profile(tmp_path)))
    for name in ("state_estimator", "torque_bridge"):
        proc = prof.processes[name]
        node = build_node(proc, prof)
        assert node.name == name
        assert set(node.inputs) == set(proc.inputs) and set(node.outputs) == set(proc.outputs)
    est = prof.processes["state_estimator"]
    assert est.inputs["robot_output"].udp == ("127.0.0.1", 25000)
    assert prof.processes["torque_bridge"].outputs["robot_input"].udp == ("127.0.0.1", 25001)
    assert est.outputs["network_state"].ttl == 1 and est.outputs["state"].ttl == 0


def test_unknown_params_are_config_errors(tmp_path: Path):
    import dataclasses

    prof = load_profile(str(_profile(tmp_path)))

    proc = dataclasses.replace(prof.processes["state_estimator"], params={"gain": 1})
    with pytest.raises(ConfigError) as exc:
        build_node(proc, prof)
    assert exc.value.key == "processes.state_estimator.params.gain"
