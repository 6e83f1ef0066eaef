"""A NaN (or wrong-length) command is rejected at once, never sent, and reported."""

from __future__ import annotations

import numpy as np

from processes.torque_bridge.bridge import SOURCE_COMMAND, SOURCE_REJECTED, BridgeParams
from tests.torque_bridge.support import BridgeRig

TAU = np.full(10, 7.0)


def test_nan_command_sends_the_fallback_not_the_previous_torques():
    rig = BridgeRig(BridgeParams(fallback="zero"))
    rig.cycle(0, TAU)
    bad = TAU.copy()
    bad[3] = np.nan
    a = rig.cycle(500, bad)
    assert a.source == SOURCE_REJECTED
    assert a.nan_rejects == 1
    assert np.all(np.isfinite(rig.torque)) and np.all(rig.torque == 0.0)
    assert "NaN" in a.status
    a = rig.cycle(1000, None)  # still the fallback until a valid command comes
    assert a.source == SOURCE_REJECTED
    a = rig.cycle(1500, np.array([np.inf] + [0.0] * 9))
    assert a.nan_rejects == 2
    a = rig.cycle(2000, TAU)
    assert a.source == SOURCE_COMMAND and a.nan_rejects == 2
    np.testing.assert_allclose(rig.torque, TAU)


def test_wrong_length_command_is_rejected():
    rig = BridgeRig(BridgeParams(fallback="zero"))
    a = rig.cycle(0, np.ones(9))
    assert a.source == SOURCE_REJECTED and a.nan_rejects == 1
    assert np.all(rig.torque == 0.0)


def test_every_packet_sent_is_finite_whatever_the_commands():
    rig = BridgeRig(BridgeParams(fallback="damping"))
    rng = np.random.default_rng(3)
    for k in range(200):
        cmd = rng.normal(0, 300, 10)
        if k % 7 == 0:
            cmd[rng.integers(10)] = np.nan
        rig.cycle(500 * k, cmd if k % 3 else None, motor_vel=float(rng.normal(0, 5)))
        assert np.all(np.isfinite(rig.torque))
        assert np.all(np.abs(rig.torque) <= np.array(BridgeParams().torque_limit))
    assert rig.applied[-1].nan_rejects == len([k for k in range(200) if k % 7 == 0 and k % 3])
