"""Fault detection and the safe mode: joint damping, always finite.

A state with NaN/inf, a fall (pelvis less than ``fall_height`` above its lowest foot contact
point: on stairs or a platform the ground is not at z = 0) or a missing MPFC plan while
walking puts the OSC into safe mode, where it commands ``u = -d * qdot`` on the ten motors
(clipped to the torque limits, NaN velocities read as zero).

A fall is terminal: the robot is on the ground, and only ``reset`` (an operator) clears it.
Every other fault is a bad input or a bad tick, and latching it for good turned one NaN
state into a fall: it clears by itself once ``recover_s`` of sim time has passed since its
cause was last seen (``try_recover``), and the controller takes the robot back.
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
    """Checks each tick; a fault stays set with its reason until ``try_recover`` (any fault
    but a fall, ``recover_s`` after its cause was last seen) or ``reset`` clears it."""

    def __init__(self, params: SafetyParams, motor_dof: np.ndarray, u_max: np.ndarray) -> None:
        self.p = params
        self.motor_dof = motor_dof
        self.u_max = u_max
        self.fault: str | None = None
        #: the fault is a fall: it never clears by itself
        self.terminal = False
        #: sim time of this tick (set by the controller first thing) and of the last tick on
        #: which the fault's cause was seen
        self.now = 0.0
        self.bad_t = -math.inf
        self.entries = 0  # faults raised (safe-mode episodes begun)
        self.recoveries = 0  # ... and cleared by themselves
        self._u = np.zeros(len(motor_dof))
        _finite_sums(self._u, self._u)  # compile (or load from numba's cache) now

    def check_state(self, q: np.ndarray, v: np.ndarray) -> str | None:
        """Raise a fault for a non-finite state (every tick, also in safe mode: it keeps the
        fault from clearing); return the current fault."""
        # a sum is NaN when any entry is NaN or +-inf (inf - inf, inf + x, NaN + x)
        if (type(q) is np.ndarray and type(v) is np.ndarray and q.dtype == np.float64
                and v.dtype == np.float64 and q.ndim == 1 and v.ndim == 1
                and q.flags.c_contiguous and v.flags.c_contiguous):
            ok = _finite_sums(q, v)  # the per-tick case, compiled (one specialisation)
        else:
            ok = math.isfinite(float(np.sum(q))) and math.isfinite(float(np.sum(v)))
        if not ok:
            self.latch("non-finite state (NaN/inf in q or v)")
        return self.fault

    def check_fall(self, pelvis_over_feet: float) -> str | None:
        """Raise a fall (terminal) when the pelvis is less than ``fall_height`` above the
        lowest foot contact point (after the kinematics); return the current fault."""
        if pelvis_over_feet < self.p.fall_height:
            self.latch(f"fall: pelvis {pelvis_over_feet:.3f} m above the lowest foot "
                       f"< {self.p.fall_height:.2f} m", terminal=True)
        return self.fault

    def check_plan(self, t: float, plan_time: float | None) -> str | None:
        """While walking: raise a fault when the newest plan is missing or too old."""
        if plan_time is None:
            self.latch("no MPFC plan while walking")
        elif t - plan_time > self.p.plan_timeout_s:
            self.latch(f"MPFC plan timeout: {1e3 * (t - plan_time):.0f} ms old"
                       f" > {1e3 * self.p.plan_timeout_s:.0f} ms")
        return self.fault

    def latch(self, reason: str, terminal: bool = False) -> None:
        """Raise a fault (QP failures, a bad plan, ...): the first reason is kept, a fall
        makes it terminal, and each call restarts the recovery clock."""
        if self.fault is None:
            self.fault = reason
            self.entries += 1
        elif terminal and not self.terminal:
            self.fault = reason  # a fall outranks the fault before it: it is what happened
        self.terminal = self.terminal or terminal
        self.bad_t = self.now

    def try_recover(self) -> bool:
        """Clear a fault that is not a fall once ``recover_s`` has passed since its cause was
        last seen; True when it cleared."""
        if self.fault is None or self.terminal or self.now - self.bad_t < self.p.recover_s:
            return False
        self.fault = None
        self.recoveries += 1
        return True

    def reset(self) -> None:
        """Clear any fault, a fall too (an operator action, never automatic)."""
        self.fault = None
        self.terminal = False

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
