"""processes.perception.robot_view, with no LCM: the camera's pose is the pelvis pose times
the mount (the same formula as the sim's camera), the legs get a box per link, the drift
correction takes the ALIP stance foot when it is down, and the submap is seeded once."""

from __future__ import annotations

import numpy as np

from processes.kinematics import AlipKinematics
from processes.perception.robot_view import LEG_LINKS, RobotView
from runtime.robot import mount_rotation


def _view() -> RobotView:
    kin = AlipKinematics()
    q = kin.m.qpos0.copy()
    q[2] = 1.0
    kin.update(q, np.zeros(kin.m.nv))
    return RobotView(kin, np.array([0.09, 0.0, 0.02]), 35.0)


def test_the_camera_is_the_pelvis_pose_times_the_mount() -> None:
    v = _view()
    pos, quat = v.camera_pose()
    pelvis_pos, pelvis_rot = v.kin.body_pose("cassie-pelvis")
    assert np.allclose(pos, pelvis_pos + pelvis_rot @ [0.09, 0.0, 0.02])
    r = np.zeros(9)
    import mujoco

    mujoco.mju_quat2Mat(r, quat)
    assert np.allclose(r.reshape(3, 3), pelvis_rot @ mount_rotation(35.0), atol=1e-9)


def test_one_box_per_leg_link_and_the_stance_foot_for_drift() -> None:
    v = _view()
    assert len(v.leg_boxes()) == 2 * len(LEG_LINKS)
    assert v.drift_foot((False, False), 0) is None
    assert np.array_equal(v.drift_foot((True, True), 1), v.kin.foot_points[1])
    assert np.array_equal(v.drift_foot((True, False), 1), v.kin.foot_points[0])  # 1 is up


def test_the_submap_is_seeded_once_when_both_feet_are_down() -> None:
    v = _view()
    assert v.seed((True, False)) is None
    first = v.seed((True, True))
    assert first is not None and np.isclose(first[1], v.kin.foot_points[:, 2].mean())
    assert v.seed((True, True)) is None
