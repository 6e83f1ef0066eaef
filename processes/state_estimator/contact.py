"""Foot contact from Cassie's leaf-spring deflection, with hysteresis.

Cassie has no foot force sensors; its shin (knee) and heel leaf springs deflect under load.
The heel spring sits in the achilles closed chain, so a static Jacobian map from spring torque
to foot force is not a clean relation; instead the normal force is a linear function of the
two deflections, ``F = -(c_shin * d_shin + c_heel * d_heel)``, whose gains were fitted against
MuJoCo's contact forces on the Menagerie model (``hw_config/gains/state_estimator.yaml``,
about 15 N rms over squats and leg lifts; a loaded spring deflects negative).

Contact turns on above ``on_n`` and off below ``off_n`` (N), so impacts and the ringing of a
swinging leg's springs do not chatter the contact flags (and with them the InEKF's contacts).
A contact also starts only while the foot moves slower than ``touchdown_speed_mps`` in the
world: a fast swing (a step-up swing reaches 2-3 m/s) loads the springs by its own inertia
past ``on_n``, and a contact declared there pins a flying foot in the InEKF and drags the
base estimate (measured: 9 cm on a 15 cm step-up).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from runtime.errors import ConfigError
from runtime.params import spec


@dataclass(frozen=True)
class ContactParams:
    """Spring-to-force gains (N/rad) and hysteresis thresholds on the force (N)."""

    shin_n_per_rad: float = spec(2100.0, lo=0.0, unit="N/rad")
    heel_n_per_rad: float = spec(2375.0, lo=0.0, unit="N/rad")
    on_n: float = spec(90.0, lo=0.0, unit="N")
    off_n: float = spec(45.0, lo=0.0, unit="N")
    #: a contact starts only on a foot slower than this (0 would never let one start; about
    #: 1: a touchdown lands at ~0.3 m/s)
    touchdown_speed_mps: float = spec(1.0, lo=0.0, lo_open=True, unit="m/s")

    def __post_init__(self) -> None:
        if self.off_n >= self.on_n:
            raise ConfigError("<ContactParams>", "off_n", f"{self.off_n} must be below on_n "
                              f"({self.on_n}) for hysteresis", f"[0, {self.on_n}) N")


class SpringContact:
    """Normal-force estimate per foot from spring deflection, and debounced contact flags."""

    def __init__(self, params: ContactParams | None = None) -> None:
        self.params = p = params or ContactParams()
        self._gain = np.array((p.shin_n_per_rad, p.heel_n_per_rad))
        self.force = np.zeros(2)
        self.in_contact = [False, False]

    def update(self, spring_defl: np.ndarray, foot_speed: np.ndarray | None = None) -> None:
        """``spring_defl`` (2, 2): (shin, heel) deflection per leg, rad; ``foot_speed`` (2):
        each foot's speed in the world, m/s (None: not gated); updates ``force`` (N) and
        ``in_contact``."""
        np.matmul(spring_defl, self._gain, out=self.force)
        np.negative(self.force, out=self.force)
        p = self.params
        for k in (0, 1):
            f = self.force[k]
            if self.in_contact[k]:
                if f < p.off_n:
                    self.in_contact[k] = False
            elif f > p.on_n and (foot_speed is None
                                 or foot_speed[k] < p.touchdown_speed_mps):
                self.in_contact[k] = True
