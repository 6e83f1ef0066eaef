"""Closed loop in the deterministic harness: real MuJoCo sim -> estimator -> scripted joint PD ->
torque bridge -> sim, with packets encoded and decoded on every hop. The estimate is compared
with the sim's ground truth at every state."""

from __future__ import annotations

import numpy as np
import pytest

from processes.torque_bridge.bridge import SOURCE_COMMAND
from tests.state_estimator.scripted import LoopRecord, errors, run_loop

SECONDS = 2.5


@pytest.fixture(scope="module")
def steps() -> LoopRecord:
    """Alternating leg lifts: single and double stance, touchdowns, the pelvis bobbing."""
    return run_loop("steps", SECONDS)


def test_estimate_follows_ground_truth_through_leg_lifts(steps: LoopRecord):
    e = errors(steps)
    assert len(e["t"]) >= SECONDS * 2000
    # the motion is real: feet lift off and land again, the pelvis moves
    assert (~e["true_contact"][:, 0]).any() and (~e["true_contact"][:, 1]).any()
    assert np.ptp(e["true_pos"][:, 2]) > 0.03
    assert np.abs(e["true_vel"][:, 2]).max() > 0.05
    # bounds: velocity RMSE 1 cm/s per axis (peak 3 cm/s), position within 1.5 cm of truth
    vel_rmse = np.sqrt((e["vel"] ** 2).mean(axis=0))
    assert (vel_rmse < 0.01).all(), vel_rmse
    assert np.abs(e["vel"]).max() < 0.03
    pos_err = np.abs(e["pos"]).max(axis=0)
    assert (pos_err < 0.015).all(), pos_err
    # contact: whenever the estimator says a foot is in contact, the sim agrees
    est, true = e["est_contact"], e["true_contact"]
    assert not (est & ~true).any()
    assert (est[:, 0] & ~est[:, 1]).any() and (est[:, 1] & ~est[:, 0]).any()  # single stance


def test_alip_state_is_com_relative_to_stance_foot(steps: LoopRecord):
    keys = [k for k in sorted(steps.states) if k in steps.truth and k > 200_000]
    n = 0
    for k in keys:
        s, t = steps.states[k], steps.truth[k]
        if s.alip_stance < 0:
            continue
        n += 1
        true_rel = np.asarray(t.com[0:2]) - np.asarray(s.alip_stance_pos[0:2])
        assert np.abs(np.asarray(s.alip_x[0:2]) - true_rel).max() < 0.02
        # the stance point is the contact foot's sole: near the ground
        assert abs(s.alip_stance_pos[2]) < 0.03
    assert n > 0.9 * len(keys)
    stances = [steps.states[k].alip_stance for k in keys]
    assert {0, 1} <= set(stances)  # the stance foot switches with the leg lifts
    first = next(i for i, s in enumerate(stances) if s >= 0)
    assert -1 not in stances[first:]  # unknown only before the first contact


def test_network_copy_is_every_tenth_state_and_contact_every_state(steps: LoopRecord):
    n = len(steps.states)
    assert len(steps.network) == (n + 9) // 10
    assert steps.network == sorted(steps.states)[::10]
    assert len(steps.contacts) == n


def test_bridge_answers_every_state_with_the_command_in_closed_loop(steps: LoopRecord):
    applied = steps.applied
    assert len(applied) == len(steps.states)  # one torque packet per state
    assert steps.harness.published["ROBOT_INPUT"] == len(steps.states)
    assert all(a.source == SOURCE_COMMAND for a in applied)
    assert applied[-1].watchdog_trips == 0 and applied[-1].nan_rejects == 0
    # the target PC saw every packet, none lost, and acked: round trip is one cycle
    link = steps.sim.tpc.link
    assert link.lost == 0 and link.malformed == 0
    # every answer but the last (in flight when the run ends): the sim reads each packet
    assert link.received == len(applied) - 1
