"""Every terrain compiles into the model with its boxes colliding with the feet: the robot
stands on each start surface, ground truth says both feet touch, and the camera sees ground."""

from __future__ import annotations

import numpy as np
import pytest

from lcmtypes import depth_frame_t, ground_truth_t
from runtime.cassie_packets import OutputPacket, encode_input


@pytest.mark.parametrize("terrain", ["flat", "stairs", "beam", "stones", "blocks", "ramped_stones",
                                     "winding_beam"])
def test_robot_stands_on_each_terrain(driver_factory, terrain: str) -> None:
    drv = driver_factory("lockstep", {"terrain": f"terrains/{terrain}.yaml"})
    node = drv.node
    state = OutputPacket()
    for k in range(100):  # 50 ms on the holder, zero torque
        state.decode(drv.sent["robot_output"][-1])
        drv.tick(command=encode_input(k, state.seq, np.zeros(10)))
    gt = ground_truth_t.decode(drv.sent["ground_truth"][-1])
    np.testing.assert_array_equal(gt.q, node.core.d.qpos)  # published at the last step
    assert gt.header.utime == 50000 and gt.num_positions == 35 and gt.num_velocities == 32
    assert gt.foot_contact == [True, True]
    assert abs(gt.q[2] - 0.95) < 0.003  # pelvis held near the IK height over the start surface
    feet = np.array(gt.foot_pos)
    assert np.all(np.abs(feet[:, 2] - node.settings.terrain.start_z) < 0.05)
    assert abs(gt.com[0] - feet[:, 0].mean()) < 0.02  # CoM above the feet
    frame = depth_frame_t.decode(drv.sent["depth"][-1])
    img = np.frombuffer(frame.data, dtype="<u2")
    assert (img > 0).mean() > 0.5  # the terrain ahead is in view and in range
