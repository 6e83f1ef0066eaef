"""In real-time mode the last torque is reused while commands are missing, and exactly 10 ms of
sim time after the last command the target PC applies zero torque (and says so)."""

from __future__ import annotations

import numpy as np

from runtime.cassie_packets import STATUS_WATCHDOG_TRIPPED, OutputPacket, encode_input
from sim.target_pc import TargetPC, make_core
from sim.terrain import flat


def _applied(tpc: TargetPC) -> np.ndarray:
    return tpc.core.d.ctrl * tpc.core.idx.gear


def test_watchdog_zeroes_torques_10ms_after_the_last_command() -> None:
    tpc = TargetPC(make_core(flat()), "realtime")
    dt = tpc.core.dt
    assert dt == 0.0005
    torque = np.array([5.0, -5.0, 10.0, -10.0, 2.0, -5.0, 5.0, -10.0, 10.0, -2.0])
    out = OutputPacket()
    out.decode(bytes(tpc.realtime_cycle(None)))
    assert out.status & STATUS_WATCHDOG_TRIPPED  # no command yet: zero torque
    np.testing.assert_array_equal(out.motor_torque, 0.0)

    out.decode(bytes(tpc.realtime_cycle(encode_input(0, out.seq, torque))))
    t_cmd = tpc.core.last_command_time
    np.testing.assert_allclose(out.motor_torque, torque)
    applied_steps = 1
    while True:
        out.decode(bytes(tpc.realtime_cycle(None)))  # no new command: reuse the last one
        if not np.any(out.motor_torque):
            break
        np.testing.assert_allclose(out.motor_torque, torque)
        assert not out.status & STATUS_WATCHDOG_TRIPPED
        applied_steps += 1
        assert applied_steps < 100, "the watchdog never tripped"
    # the torque was applied for the steps starting at t_cmd, t_cmd + 0.5 ms, ... < t_cmd + 10 ms
    assert applied_steps == 20
    assert abs(tpc.core.time - dt - t_cmd - 0.010) < 1e-9
    assert out.status & STATUS_WATCHDOG_TRIPPED
    np.testing.assert_array_equal(_applied(tpc), 0.0)

    # a command re-arms it at once
    out.decode(bytes(tpc.realtime_cycle(encode_input(1, out.seq, -torque))))
    np.testing.assert_allclose(out.motor_torque, -torque)
    assert not out.status & STATUS_WATCHDOG_TRIPPED


def test_torque_is_limited_to_the_motor_limits() -> None:
    tpc = TargetPC(make_core(flat()), "realtime")
    out = OutputPacket()
    out.decode(bytes(tpc.realtime_cycle(encode_input(0, 0, np.full(10, 1e4)))))
    np.testing.assert_allclose(out.motor_torque, tpc.core.idx.torque_limit)
    assert out.motor_torque[4] == 45.0  # the foot motor, the tight one
