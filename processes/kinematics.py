"""Cassie's forward kinematics for the laptop processes: the ALIP state (MPFC), the foot contact
points and the pelvis and leg-link poses (perception's camera pose and leg crop boxes).

Section III-A: x = (x_com, y_com, L_x, L_y), the CoM relative to the stance contact point and the
tilting angular momentum about that point, expressed in the stance frame (world axes turned by
the pelvis yaw). L about the contact point is L_com + m (p_com - p_c) x v_com. The contact point
of a foot is the midpoint of its blade (the two ends of the foot's collision capsule, at the
capsule's bottom).
"""

from __future__ import annotations

import mujoco
import numpy as np

from runtime.robot import FOOT_BLADE_ENDS as _BLADE_ENDS
from runtime.robot import FOOT_BLADE_RADIUS, SIDES, load_model

#: Ends of Cassie's foot-blade collision capsule in the foot body frame, and its radius.
FOOT_BLADE_ENDS = np.array(_BLADE_ENDS)


class AlipKinematics:
    """Forward kinematics for the ALIP state and the foot contact points (preallocated)."""

    def __init__(self, model: mujoco.MjModel | None = None) -> None:
        self.m = model if model is not None else load_model()
        self.d = mujoco.MjData(self.m)
        self.pelvis = self.m.body("cassie-pelvis").id
        self.feet = np.array([self.m.body(f"{s}-foot").id for s in SIDES])
        self.mass = float(self.m.body_subtreemass[self.pelvis])
        self.foot_points = np.zeros((2, 3))  # contact midpoints, world
        self.com = np.zeros(3)
        self.com_vel = np.zeros(3)
        self.ang_mom_com = np.zeros(3)
        self._mid_local = FOOT_BLADE_ENDS.mean(axis=0)

    def update(self, q: np.ndarray, v: np.ndarray) -> None:
        """Kinematics, CoM and subtree momentum of state (q, v) (about 5 us)."""
        d = self.d
        d.qpos[:] = q
        d.qvel[:] = v
        mujoco.mj_kinematics(self.m, d)
        mujoco.mj_comPos(self.m, d)
        mujoco.mj_comVel(self.m, d)
        mujoco.mj_subtreeVel(self.m, d)
        self.com[:] = d.subtree_com[self.pelvis]
        self.com_vel[:] = d.subtree_linvel[self.pelvis]
        self.ang_mom_com[:] = d.subtree_angmom[self.pelvis]
        for i, body in enumerate(self.feet):
            rot = d.xmat[body].reshape(3, 3)
            self.foot_points[i] = d.xpos[body] + rot @ self._mid_local
            self.foot_points[i, 2] -= FOOT_BLADE_RADIUS

    def accepts(self, q: np.ndarray, v: np.ndarray) -> bool:
        """Whether (q, v) is a state of this model: its sizes, every number finite."""
        return (q.size == self.m.nq and v.size == self.m.nv
                and bool(np.isfinite(q).all() and np.isfinite(v).all()))

    def body_pose(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """World position and rotation matrix of body ``name`` at the last ``update``."""
        i = self.m.body(name).id
        return self.d.xpos[i].copy(), self.d.xmat[i].reshape(3, 3).copy()

    def pelvis_yaw(self) -> float:
        w, x, y, z = self.d.qpos[3:7]
        return float(np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z)))

    def alip_state(self, p_contact: np.ndarray, yaw: float) -> np.ndarray:
        """(x_com, y_com, L_x, L_y) about ``p_contact``, in the frame turned by ``yaw``."""
        r = self.com - p_contact
        ang = self.ang_mom_com + self.mass * np.cross(r, self.com_vel)
        c, s = np.cos(yaw), np.sin(yaw)
        rot_t = np.array([[c, s], [-s, c]])  # world -> stance frame, in the plane
        out = np.empty(4)
        out[:2] = rot_t @ r[:2]
        out[2:] = rot_t @ ang[:2]
        return out
