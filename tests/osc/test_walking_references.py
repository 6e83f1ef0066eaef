"""Section V references: swing-foot QP (23), adaptive clearance, CoM plane (21)-(22)."""

from __future__ import annotations

import numpy as np

from processes.osc.tasks import DEFAULT_GAINS_FILE, OscGains, OscParams
from processes.osc.walking import ComHeightPlane, SwingFootTrajectory, swing_midpoint
from runtime.params import load


def test_clearance_midpoint_is_vertical_for_small_steps_and_normal_for_long_ones():
    p0 = np.zeros(3)
    # in place: straight up by c
    np.testing.assert_allclose(swing_midpoint(p0, np.zeros(3), 0.15), [0, 0, 0.15])
    # long flat step: n_p = e_z, clearance c
    np.testing.assert_allclose(swing_midpoint(p0, np.array([0.4, 0, 0]), 0.15), [0.2, 0, 0.15])
    # step up 10 cm over 40 cm: c_clear = c + min(c, dz) = 0.25 along the normal of dp
    dp = np.array([0.4, 0.0, 0.1])
    mid = swing_midpoint(p0, dp, 0.15)
    off = mid - 0.5 * dp
    assert abs(np.linalg.norm(off) - 0.25) < 1e-12
    assert abs(off @ dp) < 1e-12 and off[2] > 0  # perpendicular to dp, upward
    # step down: c_clear = c + dz (dz < 0) is smaller than c
    mid = swing_midpoint(p0, np.array([0.4, 0, -0.1]), 0.15)
    assert abs(np.linalg.norm(mid - np.array([0.2, 0, -0.05])) - 0.05) < 1e-12


def test_swing_polynomial_meets_end_mid_and_continuity_constraints_of_23():
    traj = SwingFootTrajectory(degree=8)
    p0 = np.array([0.0, -0.13, 0.0])
    des = np.array([0.3, -0.15, 0.0])
    traj.start(0.0, 0.0, 0.3, p0)
    traj.update(0.0, 0.3, des, 0.15)
    pos, vel, acc = traj.evaluate(0.0)
    np.testing.assert_allclose(pos, p0, atol=1e-9)
    np.testing.assert_allclose(vel, 0.0, atol=1e-8)
    np.testing.assert_allclose(acc, 0.0, atol=1e-6)
    np.testing.assert_allclose(traj.evaluate(0.15)[0], swing_midpoint(p0, des, 0.15), atol=1e-9)
    end = traj.evaluate(0.3)
    np.testing.assert_allclose(end[0], des, atol=1e-9)
    np.testing.assert_allclose(end[1], 0.0, atol=1e-7)
    np.testing.assert_allclose(end[2], 0.0, atol=1e-5)
    # re-plan mid-swing to a new target and a later touchdown: continuous up to acceleration
    t1 = 0.1
    before = traj.evaluate(t1)
    traj.t_prev = t1
    des2 = des + np.array([0.05, 0.02, 0.0])
    traj.update(t1 + 0.0005, 0.32, des2, 0.15)
    after = traj.evaluate(t1)
    for a, b in zip(before, after, strict=True):
        np.testing.assert_allclose(a, b, atol=1e-6)
    np.testing.assert_allclose(traj.evaluate(0.32)[0], des2, atol=1e-9)


def test_com_plane_follows_step_height_low_pass_and_clip():
    p = OscParams.from_gains(load(OscGains, DEFAULT_GAINS_FILE)).walking
    plane = ComHeightPlane(p)
    st = np.zeros(3)
    nxt = np.array([0.4, 0.0, 0.1])  # 10 cm step up, 40 cm ahead
    com = np.array([0.2, 0.0, p.com_height + 0.05])
    z, zd, kx = plane.reference(0.0, st, nxt, 0.0, com, np.array([1.0, 0, 0]))
    assert abs(kx - 0.25) < 1e-12  # (21): k_x = p_z / p_x
    # (22): H + k_x x_c = H + 0.05, within the 2.5 cm clip of the measured height
    assert abs(z - (p.com_height + 0.05)) < 1e-12
    assert abs(zd - 0.25) < 1e-12
    # clip: CoM measured far below the plane -> z_des = z_com + 2.5 cm
    low = com - np.array([0, 0, 0.2])
    z, _, _ = plane.reference(0.0005, st, nxt, 0.0, low, np.zeros(3))
    assert abs(z - (low[2] + p.com_clip)) < 1e-12
    # low-pass: a new footstep target moves k_x only by the 100 Hz first-order filter
    z, _, kx = plane.reference(0.001, st, np.array([0.4, 0, 0.0]), 0.0, com, np.zeros(3))
    a = 1.0 - np.exp(-2 * np.pi * 100.0 * 0.0005)
    assert abs(kx - 0.25 * (1 - a)) < 1e-12
    # the lateral yaw-rotated case: a step straight along the stance frame's y axis
    plane = ComHeightPlane(p)
    _, _, kx = plane.reference(0.0, st, np.array([0.0, 0.4, 0.1]), np.pi / 2, com, np.zeros(3))
    assert abs(kx - 0.25) < 1e-9


def test_a_swing_restarted_mid_flight_starts_from_the_foot_and_does_not_overshoot():
    """After a safe-mode episode the controller takes a swing back mid-flight: the new
    polynomial runs from now, from the foot's position and velocity, to the target, and
    stays between the foot and the target fore-aft (on the liftoff's time axis it had to pass
    the mid-swing waypoint within tens of ms and overshot the target by 0.19 m)."""
    traj = SwingFootTrajectory(degree=8)
    liftoff, touchdown, t = 2.0, 2.3, 2.095  # 95 ms into a 0.3 s swing
    p_now = np.array([0.49, 0.126, 0.144])
    v_now = np.array([1.1, 0.0, 0.6])
    des = np.array([0.70, 0.12, 0.0])
    traj.start(t, liftoff, touchdown, p_now, v_now)
    traj.update(t, touchdown, des, 0.1)
    pos, vel, _ = traj.evaluate(t)
    np.testing.assert_allclose(pos, p_now, atol=1e-9)
    np.testing.assert_allclose(vel, v_now, atol=1e-6)
    xs = [traj.evaluate(s)[0][0] for s in np.linspace(t, touchdown, 60)]
    assert max(xs) <= des[0] + 0.02, max(xs)
    np.testing.assert_allclose(traj.evaluate(touchdown)[0], des, atol=1e-9)


def test_a_swing_begun_at_its_liftoff_is_planned_on_the_liftoff_time_axis():
    """The restart rule leaves a swing begun on its first tick as it was."""
    traj = SwingFootTrajectory(degree=8)
    traj.start(1.0005, 1.0, 1.3, np.zeros(3), np.array([0.3, 0.0, 0.0]))
    assert traj.liftoff == 1.0 and abs(traj.T - 0.3) < 1e-12
    np.testing.assert_allclose(traj.evaluate(1.0005)[1], 0.0, atol=1e-12)
