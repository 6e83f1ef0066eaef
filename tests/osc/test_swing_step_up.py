"""Stepping up: the swing foot rises before it moves forward and is above the step before it
descends, so neither its toe (at lift-off) nor its heel (at touchdown) meets the step."""

from __future__ import annotations

import math

import numpy as np
import pytest

from processes.osc.tasks import DEFAULT_GAINS_FILE, OscGains
from processes.osc.walking import SwingFootTrajectory, swing_midpoint, swing_waypoints
from runtime.params import load

HALF_AXIS = 0.08  # Cassie's foot blade: capsule end points +-8 cm from its centre
RADIUS = 0.02  # and its radius


def _plan(traj: SwingFootTrajectory, p0: np.ndarray, des: np.ndarray, T: float = 0.3,
          dt: float = 0.0005) -> np.ndarray:
    """Re-solve every tick, as the OSC does; the reference positions over the swing."""
    traj.start(0.0, 0.0, T, p0)
    out = []
    for t in np.arange(0.0, T + 1e-9, dt):
        traj.update(t, T, des, 0.15)
        out.append(traj.evaluate(t)[0].copy())
    return np.array(out)


def _gap_to_step(path: np.ndarray, riser_x: float, top: float) -> float:
    """Smallest distance (m) from the level foot capsule along ``path`` (foot centre, sole
    height) to the solid step {x >= riser_x, z <= top}, before the heel is over the step."""
    gap = math.inf
    for x, _, z in path:
        if x - HALF_AXIS > riser_x:
            break  # the whole blade is over the step's face: this is the landing
        for s in np.linspace(-HALF_AXIS, HALF_AXIS, 17):
            px, pz = x + s, z + RADIUS  # a point of the capsule's axis
            dx, dz = max(riser_x - px, 0.0), max(pz - top, 0.0)
            gap = min(gap, math.hypot(dx, dz) - RADIUS)
    return gap


@pytest.mark.parametrize("riser_gap", [0.02, 0.05])
def test_step_up_swing_clears_a_riser_just_ahead_of_the_toe_or_just_behind_the_heel(riser_gap):
    """A 15 cm step 30 cm ahead (the 27 cm stairs' step-to gait): the riser may be 2 cm ahead
    of the toe at lift-off or 2 cm behind the heel at touchdown (the footholds leave only the
    margin beyond the foot); with riser_gap 0.05 both are the riser halfway."""
    w = load(OscGains, DEFAULT_GAINS_FILE).walking
    traj = SwingFootTrajectory(w.swing_degree, step_up_min=w.swing_step_up_min,
                               step_up_clearance=w.swing_step_up_clearance,
                               step_up_height=w.swing_step_up_height,
                               lift_tau=w.swing_lift_tau, approach_tau=w.swing_approach_tau)
    p0, des = np.array([0.0, -0.1, 0.0]), np.array([0.30, -0.1, 0.15])
    path = _plan(traj, p0, des)
    np.testing.assert_allclose(path[-1], des, atol=1e-6)
    toe_side = HALF_AXIS + RADIUS + riser_gap  # riser ahead of the toe at lift-off
    heel_side = des[0] - HALF_AXIS - RADIUS - riser_gap  # riser behind the heel at touchdown
    for riser in (toe_side, heel_side):
        assert _gap_to_step(path, riser, des[2]) > 0.01, riser
    if riser_gap == 0.02:  # the paper's midpoint alone brings the heel down onto the nosing
        paper = _plan(SwingFootTrajectory(w.swing_degree), p0, des)
        assert _gap_to_step(paper, heel_side, des[2]) < 0.01


def test_level_steps_keep_the_papers_midpoint_and_big_rises_or_drops_go_up_over_down():
    p0 = np.zeros(3)
    for des in (np.array([0.3, 0.0, 0.0]), np.array([0.3, 0.0, 0.03]),
                np.array([0.3, 0.0, -0.03])):
        wps = swing_waypoints(p0, des, 0.15, 0.05, 0.06, 0.04, 0.25, 0.8)
        assert wps == [(0.5, swing_midpoint(p0, des, 0.15))]
    wps = swing_waypoints(p0, np.array([0.3, 0.0, 0.15]), 0.15, 0.05, 0.06, 0.04, 0.25, 0.8)
    assert [tau for tau, _ in wps] == [0.25, 0.5, 0.8]
    np.testing.assert_allclose(wps[0][1], [0.0, 0.0, 0.19])  # straight above lift-off
    np.testing.assert_allclose(wps[2][1], [0.3, 0.0, 0.19])  # straight above the target
    # stepping down off an edge: up over the edge the foot stands on, then down over the
    # target from above it (the paper's c + dz would pass under the edge ahead of the toe)
    wps = swing_waypoints(p0, np.array([0.3, 0.0, -0.15]), 0.15, 0.05, 0.06, 0.04, 0.25, 0.8)
    assert [tau for tau, _ in wps] == [0.25, 0.5, 0.8]
    np.testing.assert_allclose(wps[0][1], [0.0, 0.0, 0.04])
    np.testing.assert_allclose(wps[1][1], [0.15, 0.0, 0.06])
    np.testing.assert_allclose(wps[2][1], [0.3, 0.0, -0.11])
