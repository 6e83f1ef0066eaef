"""Faults put the OSC in safe mode (joint damping) with a clear status; torques stay finite."""

from __future__ import annotations

import numpy as np

from processes.osc.controller import SAFE, STANDING, WALKING, OscController
from processes.osc.walking import DOUBLE_AFTER_LEFT, SINGLE_LEFT


class _Header:
    def __init__(self, utime: int) -> None:
        self.utime = utime


class _Plan:
    def __init__(self, utime: int, gait_state: int = DOUBLE_AFTER_LEFT) -> None:
        self.header = _Header(utime)
        self.gait_state = gait_state
        self.stance = 0
        self.stance_foot_world = [0.0, 0.13, 0.0]
        self.next_footstep_world = [0.0, -0.13, 0.0]
        self.stance_yaw = 0.0
        self.prev_switch_time_s = 0.0
        self.next_switch_time_s = 0.3
        self.ankle_torque = 0.0
        self.solve_status = 0


class _Cmd:
    mode = 0
    yaw_rate = 0.0


def test_nan_state_gives_finite_damping_torques_and_safe_status(q_stand):
    osc = OscController()
    v = np.zeros(32)
    v[osc.model.motor_dof] = 1.0
    q = q_stand.copy()
    q[10] = np.nan
    u, dbg = osc.update(0.0, q, v)
    assert dbg.mode == SAFE
    assert "non-finite" in dbg.status
    assert np.all(np.isfinite(u))
    np.testing.assert_allclose(u, -osc.params.safety.damping * 1.0)
    # NaN velocities too: still finite (NaN reads as zero velocity)
    v[osc.model.motor_dof[3]] = np.nan
    u, dbg = osc.update(0.0005, q, v)
    assert np.all(np.isfinite(u)) and u[3] == 0.0
    # a good state right after stays in safe mode: recover_s of good ticks first
    recover = osc.params.safety.recover_s
    u, dbg = osc.update(0.0005 + 0.5 * recover, q_stand, np.zeros(32))
    assert dbg.mode == SAFE
    u, dbg = osc.update(0.0005 + recover, q_stand, np.zeros(32))
    assert dbg.mode == STANDING, dbg.status
    assert osc.safety.entries == 1 and osc.safety.recoveries == 1


def test_a_nan_state_mid_walk_damps_briefly_then_walks_on_the_fresh_plan(q_stand):
    """One NaN state used to latch safe mode for good (issue 14, fault 4): now the OSC damps
    for recover_s and takes the robot back, walking, since the plan is fresh."""
    osc = OscController()
    osc.update(0.0, q_stand, np.zeros(32))
    plan = _Plan(utime=1000)
    _, dbg = osc.update(0.002, q_stand, np.zeros(32), plan, _Cmd())
    assert dbg.mode == WALKING
    bad = q_stand.copy()
    bad[0] = np.inf
    _, dbg = osc.update(0.0025, bad, np.zeros(32), plan, _Cmd())
    assert dbg.mode == SAFE
    n = round(osc.params.safety.recover_s / 0.0005)
    for k in range(1, n):
        _, dbg = osc.update(0.0025 + k * 0.0005, q_stand, np.zeros(32), plan, _Cmd())
        assert dbg.mode == SAFE
    _, dbg = osc.update(0.0025 + n * 0.0005, q_stand, np.zeros(32), plan, _Cmd())
    assert dbg.mode == WALKING, dbg.status


def test_a_stream_of_bad_states_keeps_safe_mode_until_they_stop(q_stand):
    osc = OscController()
    bad = q_stand.copy()
    bad[5] = np.nan
    for k in range(100):  # 50 ms of NaN states: the recovery clock restarts on each
        _, dbg = osc.update(k * 0.0005, bad, np.zeros(32))
        assert dbg.mode == SAFE
    assert osc.safety.entries == 1
    recover = osc.params.safety.recover_s
    _, dbg = osc.update(0.05 + recover, q_stand, np.zeros(32))
    assert dbg.mode == STANDING


def test_a_fall_stays_latched_until_an_operator_resets(q_stand):
    osc = OscController()
    fallen = q_stand.copy()
    fallen[2] = 0.2
    fallen[3:7] = (np.cos(np.pi / 4), np.sin(np.pi / 4), 0.0, 0.0)  # on its side
    _, dbg = osc.update(0.0, fallen, np.zeros(32))
    assert dbg.mode == SAFE and "fall" in dbg.status
    assert osc.safety.terminal
    _, dbg = osc.update(5.0, q_stand, np.zeros(32))  # seconds later, even standing up
    assert dbg.mode == SAFE and "fall" in dbg.status
    osc.reset()
    _, dbg = osc.update(5.001, q_stand, np.zeros(32))
    assert dbg.mode == STANDING


def test_pelvis_lying_at_its_feet_height_latches_safe_mode(q_stand):
    osc = OscController()
    q = q_stand.copy()
    q[2] = 0.2
    q[3:7] = (np.cos(np.pi / 4), np.sin(np.pi / 4), 0.0, 0.0)  # rolled 90 deg: on its side
    u, dbg = osc.update(0.0, q, np.zeros(32))
    assert dbg.mode == SAFE and "fall" in dbg.status
    assert np.all(np.isfinite(u)) and np.all(np.abs(u) <= osc.model.u_max)


def test_standing_on_a_high_landing_is_no_fall(q_stand):
    """The fall height is over the feet, not over z = 0: on the stairs' 0.9 m landing the
    robot stands (with the old absolute check a robot lying there never counted as fallen)."""
    osc = OscController()
    q = q_stand.copy()
    q[2] += 0.9
    _, dbg = osc.update(0.0, q, np.zeros(32))
    assert dbg.mode == STANDING, dbg.status


def test_missing_plan_while_walking_latches_safe_mode(q_stand):
    osc = OscController()
    osc.update(0.0, q_stand, np.zeros(32))
    plan = _Plan(utime=10_000)  # computed from the state at 10 ms
    u, dbg = osc.update(0.011, q_stand, np.zeros(32), plan, _Cmd())
    assert dbg.mode == WALKING, dbg.status
    timeout = osc.params.safety.plan_timeout_s
    u, dbg = osc.update(0.01 + 0.5 * timeout, q_stand, np.zeros(32), plan, _Cmd())
    assert dbg.mode == WALKING
    u, dbg = osc.update(0.01 + 1.5 * timeout, q_stand, np.zeros(32), plan, _Cmd())
    assert dbg.mode == SAFE and "timeout" in dbg.status
    assert np.all(np.isfinite(u))
    # the plan stays stale: after recover_s the OSC stands (it cannot walk on that plan)
    t = 0.01 + 1.5 * timeout + osc.params.safety.recover_s
    _, dbg = osc.update(t, q_stand, np.zeros(32), plan, _Cmd())
    assert dbg.mode == STANDING, dbg.status


def test_no_plan_keeps_standing_and_a_stale_plan_is_not_walked_on(q_stand):
    osc = OscController()
    _, dbg = osc.update(0.0, q_stand, np.zeros(32), None, _Cmd())
    assert dbg.mode == STANDING
    stale = _Plan(utime=0)
    _, dbg = osc.update(5.0, q_stand, np.zeros(32), stale, _Cmd())
    assert dbg.mode == STANDING


def test_non_finite_plan_while_walking_latches_safe_mode_and_is_never_walked_on(q_stand):
    osc = OscController()
    osc.update(0.0, q_stand, np.zeros(32))
    bad = _Plan(utime=0)
    bad.next_footstep_world = [np.nan, 0.0, 0.0]
    _, dbg = osc.update(0.001, q_stand, np.zeros(32), bad, _Cmd())
    assert dbg.mode == STANDING  # a bad plan is no reason to start walking
    good = _Plan(utime=1000)
    _, dbg = osc.update(0.002, q_stand, np.zeros(32), good, _Cmd())
    assert dbg.mode == WALKING
    bad.header = _Header(2000)
    u, dbg = osc.update(0.003, q_stand, np.zeros(32), bad, _Cmd())
    assert dbg.mode == SAFE and "invalid MPFC plan" in dbg.status
    assert np.all(np.isfinite(u))


def test_hand_over_to_walking_waits_for_a_double_stance_plan(q_stand):
    osc = OscController()
    osc.update(0.0, q_stand, np.zeros(32))
    _, dbg = osc.update(0.001, q_stand, np.zeros(32), _Plan(1000, SINGLE_LEFT), _Cmd())
    assert dbg.mode == STANDING and "waiting for a double-stance plan" in dbg.status
    _, dbg = osc.update(0.002, q_stand, np.zeros(32), _Plan(2000), _Cmd())
    assert dbg.mode == WALKING


def test_stand_command_while_walking_waits_for_feet_down_and_a_capturable_com(q_stand):
    osc = OscController()
    osc.update(0.0, q_stand, np.zeros(32))
    plan = _Plan(1000)  # double stance since t = 0
    _, dbg = osc.update(0.001, q_stand, np.zeros(32), plan, _Cmd())
    assert dbg.mode == WALKING
    stand = _Cmd()
    stand.mode = 1
    # too early in double stance: the landing foot may not be down yet
    _, dbg = osc.update(0.02, q_stand, np.zeros(32), plan, stand)
    assert dbg.mode == WALKING and "stand asked" in dbg.status
    # CoM moving backwards at 0.5 m/s: its capture point is behind the blades
    v = np.zeros(32)
    v[0] = -0.5
    _, dbg = osc.update(0.05, q_stand, v, plan, stand)
    assert dbg.mode == WALKING
    # both feet down, CoM at rest over them: standing
    _, dbg = osc.update(0.06, q_stand, np.zeros(32), plan, stand)
    assert dbg.mode == STANDING
