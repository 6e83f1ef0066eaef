"""Standing controller: both feet planted, CoM over the centre of the feet, pelvis level.

Used at start-up and whenever the robot is not walking. The CoM height target ramps from the
height measured on entry to the configured height, so that the hand-over from any pose (and
from walking) starts without a jump in the task references.
"""

from __future__ import annotations

import math

import numpy as np

from .model import CassieModel
from .qp import TaskRows
from .tasks import STANDING_TASKS, StandingParams, TaskLog, standing_rows

#: All four foot contact points carry force while standing.
STANDING_STANCE = np.ones(4, dtype=bool)


class StandingController:
    """Task references for standing; ``start`` captures the pose it stands from."""

    def __init__(self, params: StandingParams, nv: int) -> None:
        self.p = params
        self.t0 = 0.0
        self.z0 = params.com_height
        self.yaw = 0.0
        self.hip_yaw = [0.0, 0.0]
        self.xy0 = [0.0, 0.0]
        self.started = False
        self._errs = np.zeros(len(STANDING_TASKS))
        self._hip_des = np.zeros(2)
        # compile the kernel (or load it from numba's on-disk cache) now, not on the first tick
        idx = np.zeros(2, dtype=np.int64)
        standing_rows(np.zeros((20, 3)), np.zeros(nv + 3), np.zeros(nv),
                      np.zeros((16, 2), np.int64), np.zeros((16, 4)), 0, self._errs,
                      params.com.packed, params.pelvis.packed, params.hip_yaw.packed, 0.0, 0.0,
                      0.8, 0.0, idx, idx, self._hip_des)

    def start(self, t: float, m: CassieModel, q: np.ndarray) -> None:
        """Capture what to stand from: the CoM height above the feet, the pelvis yaw and the
        hip yaw angles (held, so a hand-back from walking does not twist planted feet)."""
        self.t0 = t
        self.z0 = float(m.com[2] - m.p_contact[:, 2].mean())
        self.yaw = m.pelvis_yaw()
        self.hip_yaw = [float(q[i]) for i in m.hip_yaw_qpos]
        self.xy0 = [float(m.com[0]), float(m.com[1])]
        self.started = True

    def add_tasks(self, rows: TaskRows, log: TaskLog, m: CassieModel, q: np.ndarray,
                  v: np.ndarray, t: float) -> np.ndarray:
        """Append the standing tasks; return the stance mask (all four points)."""
        p = self.p
        if not self.started:
            self.start(t, m, q)
        # CoM over the centre of the four contact points, height ramped towards com_height.
        pc = m.p_contact_l
        ctr = [0.25 * (pc[0][a] + pc[1][a] + pc[2][a] + pc[3][a]) for a in range(3)]
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        dz = p.com_height - self.z0
        step = p.height_rate * (t - self.t0)
        z = self.z0 + (math.copysign(min(abs(dz), step), dz) if p.height_rate > 0 else dz)
        # x, y: from the CoM position on entry to the centre of the feet over xy_ramp_s, so a
        # hand-back from walking does not ask for a CoM jump the blade feet cannot produce
        a = min(1.0, (t - self.t0) / p.xy_ramp_s) if p.xy_ramp_s > 0.0 else 1.0
        x_goal = ctr[0] + c * p.com_offset_x
        y_goal = ctr[1] + s * p.com_offset_x
        # CoM (x, y, z), pelvis level at the entry yaw, hip yaws held (Table VI)
        hip = self._hip_des
        hip[0], hip[1] = self.hip_yaw
        rows.n = standing_rows(m.kin, m.q, m.v, rows.ri, rows.rf, rows.n, self._errs,
                               p.com.packed, p.pelvis.packed, p.hip_yaw.packed,
                               self.xy0[0] + a * (x_goal - self.xy0[0]),
                               self.xy0[1] + a * (y_goal - self.xy0[1]), ctr[2] + z, self.yaw,
                               m.hip_yaw_qpos, m.hip_yaw_dof, hip)
        log.names.extend(STANDING_TASKS)
        log.errors.extend(self._errs.tolist())
        return STANDING_STANCE
