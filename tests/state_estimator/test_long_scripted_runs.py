"""Longer closed-loop runs (``pytest -m slow``): squats and sway, and a controller that dies."""

from __future__ import annotations

import numpy as np
import pytest

from processes.torque_bridge.bridge import (
    SOURCE_COMMAND,
    SOURCE_REJECTED,
    SOURCE_WATCHDOG_DAMPING,
    BridgeParams,
)
from tests.state_estimator.scripted import errors, run_loop


@pytest.mark.slow
def test_estimate_follows_ground_truth_through_six_seconds_of_squats():
    rec = run_loop("squat", 6.0)
    e = errors(rec)
    assert np.ptp(e["true_pos"][:, 2]) > 0.05 and np.abs(e["true_vel"][:, 2]).max() > 0.15
    vel_rmse = np.sqrt((e["vel"] ** 2).mean(axis=0))
    assert (vel_rmse < 0.015).all(), vel_rmse
    pos_err = np.abs(e["pos"]).max(axis=0)
    assert (pos_err < 0.02).all(), pos_err


@pytest.mark.slow
def test_bridge_damps_the_real_robot_when_the_controller_dies_and_rejects_its_nan():
    rec = run_loop("squat", 2.0, stop_after_s=1.5, nan_at_s=1.0,
                   bridge_params=BridgeParams(fallback="damping"))
    by_t = {a.header.utime: a for a in rec.applied}
    assert by_t[990_000].source == SOURCE_COMMAND
    assert by_t[1_000_000].source == SOURCE_REJECTED  # the NaN command: fallback at once
    assert by_t[1_000_500].source == SOURCE_COMMAND  # the next valid one is used again
    # silent after 1.5 s: the last command is reused for 10 ms, then damping
    assert by_t[1_509_500].source == SOURCE_COMMAND
    assert by_t[1_510_000].source == SOURCE_WATCHDOG_DAMPING
    last = rec.applied[-1]
    assert last.watchdog_trips == 1 and last.nan_rejects == 1
    # the target PC kept getting packets: its own watchdog never tripped
    assert not rec.sim.core.watchdog_tripped
    assert all(np.isfinite(a.torque).all() for a in rec.applied)
