"""Fault detection and the safe mode: joint damping, always finite.

A state with NaN/inf, a fall (pelvis less than ``fall_height`` above its lowest foot contact
point: on stairs or a platform the ground is not at z = 0) or a missing MPFC plan while
walking latches the OSC into safe mode, where it commands ``u = -d * qdot`` on the ten motors
(clipped to the torque limits, NaN velocities read as zero). ``reset`` clears the latch.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from .tasks import SafetyParams


@numba.njit(cache=True, nogil=True)
def _finite_sums(q: np.ndarray, v: np.ndarray) -> bool:
    """Both sums finite: false when any entry is NaN or +-inf (inf - inf, inf + x, NaN + x)."""
    s = 0.0
    for x in q:
        s += x
    t = 0.0
    for x in v:
        t += x
    return math.isfinite(s) and math.isfinite(t)


class SafetyMonitor:
    """Checks each state; once a fault is seen it stays latched with its reason."""

    def __init__(self, params: SafetyParams, motor_dof: np.ndarray, u_max: np.ndarray) -> None:
        self.p = params
        self.motor_dof = motor_dof
        self.u_max = u_max
        self.fault: str | None = None
        self._u = np.zeros(len(motor_dof))
        _finite_sums(self._u, self._u)  # compile (or load from numba's cache) now

    def check_state(self, q: np.ndarray, v: np.ndarray) -> str | None:
        """Latch and return a fault for a non-finite state, else the current latch."""
        # a sum is NaN when any entry is NaN or +-inf (inf - inf, inf + x, NaN + x)
        if self.fault is None:
            if (type(q) is np.ndarray and type(v) is np.ndarray and q.dtype == np.float64
                    and v.dtype == np.float64 and q.ndim == 1 and v.ndim == 1
                    and q.flags.c_contiguous and v.flags.c_contiguous):
                ok = _finite_sums(q, v)  # the per-tick case, compiled (one specialisation)
            else:
                ok = math.isfinite(float(np.sum(q))) and math.isfinite(float(np.sum(v)))
            if not ok:
                self.fault = "non-finite state (NaN/inf in q or v)"
        return self.fault

    def check_fall(self, pelvis_over_feet: float) -> str | None:
        """Latch and return a fall when the pelvis is less than ``fall_height`` above the
        lowest foot contact point (after the kinematics), else the current latch."""
        if self.fault is None and pelvis_over_feet < self.p.fall_height:
            self.fault = (f"fall: pelvis {pelvis_over_feet:.3f} m above the lowest foot "
                          f"< {self.p.fall_height:.2f} m")
        return self.fault

    def check_plan(self, t: float, plan_time: float | None) -> str | None:
        """While walking: latch a fault when the newest plan is missing or too old."""
        if self.fault is None:
            if plan_time is None:
                self.fault = "no MPFC plan while walking"
            elif t - plan_time > self.p.plan_timeout_s:
                self.fault = (f"MPFC plan timeout: {1e3 * (t - plan_time):.0f} ms old"
                              f" > {1e3 * self.p.plan_timeout_s:.0f} ms")
        return self.fault

    def latch(self, reason: str) -> None:
        """Latch a fault found elsewhere (QP failures, a bad plan); the first reason wins."""
        if self.fault is None:
            self.fault = reason

    def reset(self) -> None:
        """Clear the latch (an operator action, never automatic)."""
        self.fault = None

    def damping(self, v: np.ndarray) -> np.ndarray:
        """Joint damping torques (finite even when ``v`` holds NaN)."""
        u = self._u
        for i, dof in enumerate(self.motor_dof):
            vi = float(v[dof]) if len(v) > dof else 0.0
            if not math.isfinite(vi):
                vi = 0.0
            u[i] = -self.p.damping[i] * vi
        np.clip(u, -self.u_max, self.u_max, out=u)
        return u.copy()
