"""The estimator built from a profile (``runtime.builder.build_node``): its one param
(``truth_state``) and a bad gains file (an unknown key, a value out of range, on_n not above
off_n) are ConfigErrors naming the file, the dotted key and what is allowed."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.conftest import build_one, config_error


def test_the_shipped_settings_build(tmp_path: Path) -> None:
    node = build_one(tmp_path, "state_estimator")
    assert node.name == "state_estimator" and node.params.network_every == 10
    assert node.params.init.xy_m == (0.0, 0.0)


def test_a_gains_key_as_a_param_is_an_unknown_key_naming_the_profile(tmp_path: Path) -> None:
    err = config_error(tmp_path, "state_estimator", params={"network_every": 5})
    assert str(err) == (f"{tmp_path / 'one.yaml'}: processes.state_estimator.params."
                              "network_every: unknown key (allowed: truth_state)")


def test_the_true_state_without_its_input_names_what_to_add(tmp_path: Path) -> None:
    err = config_error(tmp_path, "state_estimator", params={"truth_state": True})
    assert str(err) == (
        f"{tmp_path / 'one.yaml'}: processes.state_estimator.params.truth_state: true, but "
        "the process has no ground_truth input (allowed: false, or inputs: {ground_truth: "
        "ground_truth} with the sim's output_rate_hz.ground_truth at its step rate)")


@pytest.mark.parametrize(("change", "message"), [
    (lambda g: g["inekf"].__setitem__("gyros", 0.1),
     "inekf.gyros: unknown key (allowed: accel, contact, gyro, init_pos, init_rot, init_vel, "
     "kinematics, swing)"),
    (lambda g: g["inekf"].__setitem__("gyro", 0.0),
     "inekf.gyro: out of range: 0.0 (allowed: (0.0, inf] rad/s/sqrt(Hz))"),
    (lambda g: g.__setitem__("network_every", 2.5),
     "network_every: must be an integer, got 2.5 (allowed: [1, inf])"),
    (lambda g: g["init"].__setitem__("xy_m", [1.0]),
     "init.xy_m: must be a list of 2, got 1: [1.0]"),
    (lambda g: g["contact"].__setitem__("off_n", 95.0),
     "contact.off_n: 95.0 must be below on_n (90.0) for hysteresis (allowed: [0, 90.0) N)"),
])
def test_a_bad_gains_file_names_file_key_and_allowed(tmp_path: Path, change, message) -> None:
    err = config_error(tmp_path, "state_estimator", gains=change)
    assert str(err) == f"{tmp_path / 'gains.yaml'}: {message}"
