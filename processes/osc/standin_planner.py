"""A simple ALIP foot-placement planner: MPFC's stand-in in OSC tests and benchmarks, and the
OSC's own planner while the MPFC's plans are lost (``fallback.PlanFallback``).

Not the MPFC of Section IV: fixed step timing (T_ss, T_ds), no footholds, zero ankle torque.
The next footstep is the one-step ALIP deadbeat placement that brings the angular momentum
about the contact point at the end of the next step to that of a periodic gait at the desired
velocity and step width, in the frame of a fixed heading. It emits ``mpfc_output_t`` messages
so the OSC sees exactly what it would get from the real planner. By default the ground is
flat at z = 0; ``measured_ground`` keeps each stance foot's measured height (steps in place on
whatever the robot stands on).
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

from lcmtypes import mpfc_output_t

from .model import LEFT, RIGHT, CassieModel

_G = 9.81


class StandInPlanner:
    """Step timing and ALIP foot placement; call ``plan(t, q, v)`` at the planner's rate."""

    def __init__(self, model: CassieModel, vdes: tuple[float, float] = (0.0, 0.0),
                 step_width: float = 0.26, H: float = 0.85, t_ss: float = 0.3,
                 t_ds: float = 0.1, measured_ground: bool = False) -> None:
        self.m = model
        self.measured_ground = measured_ground
        self.yaw = 0.0  # the heading of the stance frame the gait is planned in
        #: stay in double stance (lift-off postponed, 50 ms ahead at each call): the plan
        #: fallback waits there for the MPFC's gait to come round to the same stance foot
        self.hold_double = False
        self.vdes = np.array(vdes, dtype=float)
        self.w = step_width
        self.H = H
        self.t_ss, self.t_ds = t_ss, t_ds
        self.lam = math.sqrt(_G / H)  # ALIP natural frequency
        self.stance = LEFT
        self.single = False
        self.t_switch: float | None = None
        self.t_next = 0.0
        self.stance_pos = np.zeros(3)
        self.next_pos = np.zeros(3)
        #: the seeding plan's footstep, kept until that step's touchdown (``seed``)
        self._seeded_step: np.ndarray | None = None
        #: per foot, the ground height under it, read at the liftoff of the other foot (when
        #: it has stood through double stance): ``measured_ground``'s heights
        self._ground_z: list[float | None] = [None, None]

    def _foot(self, side: int) -> np.ndarray:
        """A foot's contact midpoint, on the flat ground (z = 0) unless ``measured_ground``:
        then at the ground height last read under that foot while it stood (its height at the
        planned touchdown is taken only for a foot never seen standing). Read at the planned
        touchdown, a foot that landed late was still above the ground: the heights ratcheted
        up each step and the pelvis rose 5 cm in 5 s of stepping in place (measured)."""
        p = self.m.foot_center(side).copy()
        if not self.measured_ground:
            p[2] = 0.0
        elif self._ground_z[side] is not None:
            p[2] = self._ground_z[side]
        return p

    def seed(self, plan: mpfc_output_t) -> None:
        """Take over the gait where ``plan`` (the MPFC's last) has it: the same stance foot,
        phase, switch times and heading, so the swing in progress lands where it was going."""
        self.stance = int(plan.stance)
        self.single = int(plan.gait_state) in (0, 1)
        self.t_switch = float(plan.prev_switch_time_s)
        self.t_next = float(plan.next_switch_time_s)
        self.stance_pos = np.array(plan.stance_foot_world, dtype=float)
        self.yaw = float(plan.stance_yaw)
        self._ground_z = [None, None]
        self._ground_z[self.stance] = float(self.stance_pos[2])
        step = np.asarray(plan.next_footstep_world, dtype=float)
        self._seeded_step = step.copy() if step.shape == (3,) and np.isfinite(step).all() \
            else None

    def plan(self, t: float, q: np.ndarray, v: np.ndarray) -> mpfc_output_t:
        """Advance the gait clock to t and return the plan for the state (q, v)."""
        m = self.m
        m.update(q, v)
        if self.t_switch is None:  # start: double stance, then left single stance
            self.t_switch = t
            self.t_next = t + self.t_ds
            self.single = False
            self.stance = LEFT
            self.stance_pos = self._foot(LEFT)
        if self.hold_double and not self.single and self.t_next < t + 0.05:
            self.t_next = t + 0.05
        if self.single and t >= self.t_next:  # planned touchdown: the swing foot lands
            self._seeded_step = None  # the seeding plan's step is taken: plan our own
            self.stance = 1 - self.stance
            self.stance_pos = self._foot(self.stance)
            self.single = False
            self.t_switch = self.t_next
            self.t_next = self.t_switch + self.t_ds
        elif not self.single and t >= self.t_next:  # liftoff of the other foot
            self.single = True
            if self.measured_ground:  # the stance foot has stood through double stance
                self._ground_z[self.stance] = float(m.foot_center(self.stance)[2])
            self.t_switch = self.t_next
            self.t_next = self.t_switch + self.t_ss

        # ALIP state about the stance foot: angular momentum about the contact point,
        # L = L_com + m (c - p) x v_c (the ALIP's state, Section III-A).
        mass, H, l = m.mass, self.H, self.lam  # noqa: E741
        mujoco.mj_subtreeVel(m.m, m.d)
        L = m.d.subtree_angmom[m.pelvis_body] + mass * np.cross(m.com - self.stance_pos, m.com_vel)
        # in the heading frame (x forward, y left): rotate world x, y by -yaw
        cy, sy = math.cos(self.yaw), math.sin(self.yaw)
        dx, dy = m.com[0] - self.stance_pos[0], m.com[1] - self.stance_pos[1]
        x = np.array((cy * dx + sy * dy, -sy * dx + cy * dy))
        Lx, Ly = cy * float(L[0]) + sy * float(L[1]), -sy * float(L[0]) + cy * float(L[1])
        # Predict to the next touchdown: the OSC's double stance has no horizontal CoM task, so
        # the CoM coasts with constant L through it; single stance is the ALIP pendulum (1).
        mH = mass * H
        if not self.single:
            tds = max(self.t_next - t, 0.0)
            x = x + np.array([Ly, -Lx]) * (tds / mH)
            T = self.t_ss
        else:
            T = max(self.t_next - t, 0.0)
        c, s = math.cosh(l * T), math.sinh(l * T)
        xT = c * x[0] + s * Ly / (mH * l)
        LyT = mH * l * s * x[0] + c * Ly
        yT = c * x[1] - s * Lx / (mH * l)
        LxT = -mH * l * s * x[1] + c * Lx
        # the foot that lands next is the stance of the next step: coast t_ds, then t_ss
        nxt = 1 - self.stance
        cn, sn = math.cosh(l * self.t_ss), math.sinh(l * self.t_ss)
        Ly_des = mH * self.vdes[0]
        sign = 1.0 if nxt == LEFT else -1.0
        Lx_des = sign * mH * (self.w / 2) * l * math.tanh(l * self.t_ss / 2) - mH * self.vdes[1]
        x0 = (Ly_des - cn * LyT) / (mH * l * sn) - LyT * self.t_ds / mH
        y0 = (cn * LxT - Lx_des) / (mH * l * sn) + LxT * self.t_ds / mH
        # the step in the heading frame; keep the feet from crossing and from stretching
        fwd, side = xT - x0, yT - y0
        side = min(max(side, -0.6), -0.08) if nxt == RIGHT else max(min(side, 0.6), 0.08)
        fwd = max(min(fwd, 0.4), -0.4)
        # stepping in place, the swing foot comes down on the ground it lifted off from
        gz = self._ground_z[nxt] if self.measured_ground else None
        target = np.array([self.stance_pos[0] + cy * fwd - sy * side,
                           self.stance_pos[1] + sy * fwd + cy * side,
                           self.stance_pos[2] if gz is None else gz])
        if self._seeded_step is not None:
            # Until the seeding plan's step lands, its footstep stands: a new target mid-swing
            # (a one-step stop from walking speed asks 0.4 m) made the foot overshoot by 0.3 m
            # and 0.3 m up, and the robot fell stepping in place (measured, MPFC killed at 2 s).
            target = self._seeded_step.copy()
        self.next_pos = target

        msg = mpfc_output_t()
        msg.header.utime = round(t * 1e6)
        if self.single:
            msg.gait_state = 0 if self.stance == LEFT else 1
        else:
            msg.gait_state = 2 if self.stance == LEFT else 3
        msg.stance = self.stance
        msg.stance_foot_world = self.stance_pos.tolist()
        msg.next_footstep_world = target.tolist()
        msg.next_footstep = (target - self.stance_pos).tolist()
        msg.stance_yaw = self.yaw
        msg.prev_switch_time_s = float(self.t_switch)
        msg.next_switch_time_s = float(self.t_next)  # liftoff in double stance, else touchdown
        msg.ankle_torque = 0.0
        msg.desired_velocity = self.vdes.tolist()
        msg.num_footsteps = 1
        msg.footsteps_world = [target.tolist()]
        msg.solve_status = 0
        return msg
