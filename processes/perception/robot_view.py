"""Where the robot is, for the map: the camera's pose, the legs to crop, the foot that
corrects drift and the ground under the feet at the start (Section VII-A/B), from the robot's
kinematics and its contacts; no LCM in it.

The camera is mounted on the pelvis (the mount position and pitch: ``runtime.robot``): its
pose is the estimated pelvis pose times the mount. The robot's own legs are cut out of the
point cloud with boxes around the leg links. The stance foot's height corrects the map's drift
(Section VII-B): the ALIP filter's stance when that foot is down, else a foot that is. The
first time both feet are down, the unknown cells around them take the feet's height (the
camera never sees the ground the robot starts on).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from processes.kinematics import AlipKinematics
from processes.perception.elevation_map import CropBox
from runtime.robot import PELVIS_BODY, SIDES, mount_rotation

#: Leg links cropped from the point cloud, with the half extents of their boxes (m), body frame.
LEG_LINKS = {
    "shin": (0.28, 0.06, 0.06),
    "tarsus": (0.28, 0.06, 0.06),
    "foot": (0.14, 0.06, 0.05),
    "knee": (0.12, 0.07, 0.07),
}


def rot_to_quat(r: np.ndarray) -> np.ndarray:
    """Rotation matrix -> quaternion (w, x, y, z)."""
    import mujoco

    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, np.ascontiguousarray(r).reshape(-1))
    return q


class RobotView:
    """The robot as the map needs it at one frame, from its kinematics (see the docstring)."""

    def __init__(self, kin: AlipKinematics, mount_pos: np.ndarray, pitch_down_deg: float) -> None:
        self.kin = kin
        self.mount_pos = np.asarray(mount_pos, dtype=float)
        self.r_pc = mount_rotation(pitch_down_deg)
        self.seeded = False  # the initial submap under the feet has been filled

    def camera_pose(self) -> tuple[np.ndarray, np.ndarray]:
        """(position, quaternion w x y z) of the camera: the pelvis pose times the mount."""
        pelvis_pos, pelvis_rot = self.kin.body_pose(PELVIS_BODY)
        return pelvis_pos + pelvis_rot @ self.mount_pos, rot_to_quat(pelvis_rot @ self.r_pc)

    def leg_boxes(self) -> list[CropBox]:
        """A box around each leg link, in the world (the legs are cut out of the cloud)."""
        boxes = []
        for side in SIDES:
            for link, half in LEG_LINKS.items():
                pos, rot = self.kin.body_pose(f"{side}-{link}")
                boxes.append(CropBox(center=pos, rotation=rot, half_extents=np.array(half)))
        return boxes

    def drift_foot(self, in_contact: Sequence[bool], alip_stance: int) -> np.ndarray | None:
        """The contact point whose height corrects the map's drift, or None with no foot
        down: the ALIP filter's stance foot when it is down, else the first foot that is."""
        if not any(in_contact):
            return None
        stance = 0 if in_contact[0] else 1
        if alip_stance in (0, 1) and in_contact[alip_stance]:
            stance = alip_stance
        return self.kin.foot_points[stance]

    def seed(self, in_contact: Sequence[bool]) -> tuple[np.ndarray, float, float] | None:
        """(feet's centre xy, their height, the pelvis yaw) the first time both feet are
        down, for the initial submap; None before and after."""
        if self.seeded or not all(in_contact):
            return None
        self.seeded = True
        feet = np.asarray(self.kin.foot_points, dtype=float)
        return feet[:, :2].mean(axis=0), float(feet[:, 2].mean()), self.kin.pelvis_yaw()
