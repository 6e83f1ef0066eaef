"""The bridge's watchdog: 10 ms of state (sim) time without a fresh command -> fallback."""

from __future__ import annotations

import numpy as np

from processes.torque_bridge.bridge import (
    SOURCE_COMMAND,
    SOURCE_WATCHDOG_DAMPING,
    SOURCE_WATCHDOG_ZERO,
    BridgeParams,
)
from tests.torque_bridge.support import BridgeRig, command

TAU = np.linspace(-20.0, 25.0, 10)


def test_command_passes_then_watchdog_sends_zero_after_10ms_and_recovers():
    rig = BridgeRig(BridgeParams(fallback="zero"))
    for k in range(20):  # 10 ms of commands at 2 kHz
        a = rig.cycle(500 * k, TAU)
        assert a.source == SOURCE_COMMAND
        np.testing.assert_allclose(rig.torque, TAU)
    last_cmd = 500 * 19
    k = 20
    while True:  # the controller goes silent; states keep coming
        t = 500 * k
        a = rig.cycle(t, None, motor_vel=3.0)
        if t - last_cmd < 10_000:
            assert a.source == SOURCE_COMMAND, (t - last_cmd)
            np.testing.assert_allclose(rig.torque, TAU)  # last command reused until then
        else:
            break
        k += 1
    assert t - last_cmd == 10_000  # trips exactly at 10 ms of sim time
    assert a.source == SOURCE_WATCHDOG_ZERO
    assert a.watchdog_trips == 1
    assert np.all(rig.torque == 0.0)
    assert "no fresh command" in a.status
    for j in range(1, 10):  # stays tripped, counted once
        a = rig.cycle(t + 500 * j, None)
        assert a.source == SOURCE_WATCHDOG_ZERO and a.watchdog_trips == 1
    a = rig.cycle(t + 5000, TAU)  # commands resume
    assert a.source == SOURCE_COMMAND and a.watchdog_trips == 1
    np.testing.assert_allclose(rig.torque, TAU)
    assert len(rig.packets) == len(rig.applied)  # one packet per state, always


def test_damping_fallback_opposes_motor_velocity():
    params = BridgeParams(fallback="damping")
    rig = BridgeRig(params)
    a = rig.cycle(0, None, motor_vel=2.0)  # no controller yet: zero (the holder stays on)
    assert a.source == SOURCE_WATCHDOG_ZERO
    assert a.watchdog_trips == 0  # never had a command: not a trip
    assert np.all(rig.torque == 0.0)
    rig.cycle(500, TAU)
    a = rig.cycle(500 + 10_000, None, motor_vel=-1.0)
    assert a.source == SOURCE_WATCHDOG_DAMPING and a.watchdog_trips == 1
    np.testing.assert_allclose(rig.torque, 1.0 * np.array(params.damping_kd))


def test_command_from_the_future_of_the_state_is_stale():
    rig = BridgeRig(BridgeParams(fallback="zero"))
    rig.cycle(5_000_000, TAU)
    # a command stamped 4 s ahead of the states: left over from before a sim restart
    rig.h.inject("CMD", command(9_000_000, TAU), at_us=5_000_500)
    a = rig.cycle(5_020_000, None)
    assert a.source == SOURCE_WATCHDOG_ZERO
