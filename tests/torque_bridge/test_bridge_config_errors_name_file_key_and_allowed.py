"""The torque bridge built from a profile (``runtime.builder.build_node``): an unknown or bad
param, and an unknown or bad key of its gains file, are ConfigErrors naming the file, the
dotted key and what is allowed; good ones reach the node."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.conftest import build_one, config_error


def test_params_and_gains_reach_the_node(tmp_path: Path) -> None:
    node = build_one(tmp_path, "torque_bridge",
                     params={"answer_on": "state", "fill_hz": 1000, "release_after_s": 1},
                     gains=lambda g: g["torque_limit_nm"].__setitem__("foot", 40))
    assert node.answer_on == "state" and node.release_after_us == 1_000_000
    assert node.params.torque_limit == (112.5, 112.5, 195.2, 195.2, 40.0) * 2
    assert node.params.watchdog_s == 0.010 and node.params.fallback == "damping"


@pytest.mark.parametrize(("params", "message"), [
    ({"answer": "state"}, "params.answer: unknown key (allowed: answer_on, fill_hz, "
                          "release_after_s)"),
    ({"answer_on": "never"}, "params.answer_on: 'never' is not one of the allowed values "
                             "(allowed: auto, command, state, torque)"),
    ({"fill_hz": 0}, "params.fill_hz: out of range: 0 (allowed: (0.0, 2000.0] Hz)"),
    ({"release_after_s": "soon"}, "params.release_after_s: must be a number, got 'soon' "
                                  "(allowed: [0.0, 60.0] s)"),
])
def test_a_bad_param_names_the_profile_key_and_allowed(tmp_path: Path, params, message) -> None:
    err = config_error(tmp_path, "torque_bridge", params=params)
    assert str(err) == f"{tmp_path / 'one.yaml'}: processes.torque_bridge.{message}"


@pytest.mark.parametrize(("change", "message"), [
    (lambda g: g.__setitem__("watchdog", 10), "watchdog: unknown key (allowed: damping_kd, "
     "fallback, release_holder, torque_limit_nm, watchdog_ms)"),
    (lambda g: g["damping_kd"].__setitem__("ankle", 1.0), "damping_kd.ankle: unknown key "
     "(allowed: foot, hip_pitch, hip_roll, hip_yaw, knee)"),
    (lambda g: g["torque_limit_nm"].__setitem__("knee", 0.0),
     "torque_limit_nm.knee: out of range: 0.0 (allowed: (0.0, 1000.0] N m)"),
    (lambda g: g["torque_limit_nm"].pop("knee"),
     "torque_limit_nm.knee: is required (allowed: (0.0, 1000.0] N m)"),
    (lambda g: g.__setitem__("fallback", "brake"),
     "fallback: 'brake' is not one of the allowed values (allowed: zero, damping)"),
    (lambda g: g.__setitem__("watchdog_ms", 0.1),
     "watchdog_ms: out of range: 0.1 (allowed: [0.5, 1000.0] ms)"),
])
def test_a_bad_gains_file_names_file_key_and_allowed(tmp_path: Path, change, message) -> None:
    err = config_error(tmp_path, "torque_bridge", gains=change)
    assert str(err) == f"{tmp_path / 'gains.yaml'}: {message}"
