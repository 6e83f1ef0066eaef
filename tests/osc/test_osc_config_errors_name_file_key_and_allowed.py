"""The OSC built from a profile (``runtime.builder.build_node``): an unknown or bad param, and
an unknown or bad key of its gains file (a task's gains, a range, plan_fallback_s above
plan_timeout_s), are ConfigErrors naming the file, the dotted key and what is allowed."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.conftest import build_one, config_error


def test_params_and_gains_reach_the_node(tmp_path: Path) -> None:
    node = build_one(tmp_path, "osc", params={"start": "stand", "hold_until_plan": True,
                                              "stand_first_s": 1.2},
                     gains=lambda g: g["walking"].__setitem__("swing_clearance", 0.12))
    assert node._default_command is None and node._hold_until_plan
    assert node._stand_first_us == 1_200_000
    w = node.params.walking
    assert w.swing_clearance == 0.12 and list(w.swing_foot.kd) == [35.0, 35.0, 25.0]
    assert list(w.toe.packed[:, 0]) == [1.0, 1500.0, 10.0]


@pytest.mark.parametrize(("params", "message"), [
    ({"gains_file": "gains/osc.yaml"}, "params.gains_file: unknown key (allowed: "
                                       "hold_until_plan, soft_start_s, stand_first_s, start)"),
    ({"start": "run"}, "params.start: 'run' is not one of the allowed values "
                       "(allowed: walk, stand)"),
    ({"hold_until_plan": "yes"}, "params.hold_until_plan: must be true or false, got 'yes' "
                                 "(allowed: true, false)"),
    ({"stand_first_s": -2}, "params.stand_first_s: out of range: -2 (allowed: [0.0, 60.0] s)"),
])
def test_a_bad_param_names_the_profile_key_and_allowed(tmp_path: Path, params, message) -> None:
    err = config_error(tmp_path, "osc", params=params)
    assert str(err) == f"{tmp_path / 'one.yaml'}: processes.osc.{message}"


@pytest.mark.parametrize(("change", "message"), [
    (lambda g: g["walking"]["swing_foot"].__setitem__("ki", [0, 0, 0]),
     "walking.swing_foot.ki: unknown key (allowed: kd, kp, w)"),
    (lambda g: g["walking"]["toe"].__setitem__("kp", -1),
     "walking.toe.kp: out of range: -1 (allowed: [0.0, inf])"),
    (lambda g: g["standing"]["com"].__setitem__("kd", [4, 4]),
     "standing.com.kd: must be a list of 3, got 2"),
    (lambda g: g["qp"].__setitem__("mu", 0.0), "qp.mu: out of range: 0.0 (allowed: (0.0, 2.0])"),
    (lambda g: g.__setitem__("springs", "soft"),
     "springs: 'soft' is not one of the allowed values (allowed: rigid_swing, measured)"),
    (lambda g: g["safety"].__setitem__("plan_fallback_s", 0.5),
     "safety.plan_fallback_s: 0.5 is above plan_timeout_s (0.2) (allowed: [0.0, 0.2] s)"),
    (lambda g: g["safety"].__setitem__("damping", [1.0] * 9),
     "safety.damping: must be a list of 10, got 9"),
])
def test_a_bad_gains_file_names_file_key_and_allowed(tmp_path: Path, change, message) -> None:
    err = config_error(tmp_path, "osc", gains=change)
    assert str(err).startswith(f"{tmp_path / 'gains.yaml'}: {message}")
