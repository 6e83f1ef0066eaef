"""Each motor's torque is clamped to its joint-side limit from hw_config, and counted."""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np

from processes.state_estimator.kinematics import load_model
from processes.torque_bridge.bridge import (
    SOURCE_COMMAND,
    SOURCE_WATCHDOG_DAMPING,
    BridgeGains,
    BridgeParams,
)
from processes.torque_bridge.process import motor_dofs
from runtime.cassie_packets import MOTOR_NAMES
from runtime.params import load
from tests.torque_bridge.support import MOTOR_DOFS, BridgeRig

GAINS = Path(__file__).resolve().parents[2] / "hw_config" / "gains" / "torque_bridge.yaml"


def test_limits_in_hw_config_are_the_models_motor_limits():
    params = BridgeParams.from_gains(load(BridgeGains, GAINS))
    m = load_model()
    act = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_ACTUATOR, n) for n in MOTOR_NAMES]
    model_limit = m.actuator_gear[act, 0] * np.abs(m.actuator_ctrlrange[act]).max(axis=1)
    np.testing.assert_allclose(params.torque_limit, model_limit)
    assert params.watchdog_s == 0.010
    assert list(motor_dofs(m)) == MOTOR_DOFS


def test_over_limit_torques_are_clamped_per_motor_and_counted():
    params = BridgeParams.from_gains(load(BridgeGains, GAINS))
    limit = np.array(params.torque_limit)
    rig = BridgeRig(params)
    cmd = np.array([500.0, -500.0, 10.0, -10.0, 46.0, 0.0, 112.4, -300.0, 195.2, -45.5])
    a = rig.cycle(0, cmd)
    assert a.source == SOURCE_COMMAND
    expect = np.clip(cmd, -limit, limit)
    np.testing.assert_allclose(rig.torque, expect)
    np.testing.assert_allclose(a.commanded, cmd)  # as received, for the log
    assert a.clamp_count == 5  # motors 0, 1, 4, 7, 9
    a = rig.cycle(500, cmd)
    assert a.clamp_count == 10
    a = rig.cycle(1000, np.zeros(10))
    assert a.clamp_count == 10
    assert np.all(np.abs(rig.torque) <= limit)


def test_damping_fallback_is_clamped_too():
    rig = BridgeRig(BridgeParams(fallback="damping"))
    rig.cycle(0, np.zeros(10))
    a = rig.cycle(20_000, None, motor_vel=1000.0)  # wild velocity: kd * v would be 5000 N m
    assert a.source == SOURCE_WATCHDOG_DAMPING
    np.testing.assert_allclose(np.abs(rig.torque), np.array(BridgeParams().torque_limit))
    assert a.clamp_count == 10
