"""Kalman filter on the ALIP state (paper Section IX-A-2), with filterpy.

The ALIP state ``x = (x_com, y_com, L_x, L_y)`` (Section III-A) is the horizontal CoM position
relative to the stance contact point and the angular momentum about that point. Impacts and
hip-roll compliance make the raw momentum spiky; the paper smooths it with a Kalman filter whose
model is the ALIP dynamics (1), with full-state measurement and a much larger measurement noise
on the angular momentum than on the CoM position. When the stance foot changes the state's
coordinates jump (the reset map (8)), so the filter restarts from the measurement there.

The ankle-torque input of (1) is left out of the prediction (treated as process noise on
``L_y``): the stance ankle moment about the contact point is not measured directly.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from filterpy.kalman import KalmanFilter
from scipy.linalg import expm

from runtime.params import spec


@dataclass(frozen=True)
class AlipFilterParams:
    """ALIP model and noise (std devs): measurement noise is high on L, low on the CoM."""

    height: float = spec(0.85, lo=0.0, lo_open=True, unit="m")  # H of (1) (Table V)
    meas_pos: float = spec(0.005, lo=0.0, lo_open=True, unit="m")
    meas_mom: float = spec(1.0, lo=0.0, lo_open=True, unit="kg m^2/s")
    #: model error on the CoM rate
    proc_pos: float = spec(0.02, lo=0.0, lo_open=True, unit="m/sqrt(s)")
    #: unmodelled ankle torque, impacts
    proc_mom: float = spec(4.0, lo=0.0, lo_open=True, unit="kg m^2/s/sqrt(s)")


def alip_a(mass: float, height: float, gravity: float) -> np.ndarray:
    """The A matrix of (1): d/dt (x, y, Lx, Ly)."""
    return np.array(
        [
            [0.0, 0.0, 0.0, 1.0 / (mass * height)],
            [0.0, 0.0, -1.0 / (mass * height), 0.0],
            [0.0, -mass * gravity, 0.0, 0.0],
            [mass * gravity, 0.0, 0.0, 0.0],
        ]
    )


class AlipKalman:
    """filterpy ``KalmanFilter`` with ALIP dynamics, re-seeded at every stance switch."""

    def __init__(
        self, mass: float, params: AlipFilterParams | None = None, gravity: float = 9.81
    ) -> None:
        self.params = p = params or AlipFilterParams()
        self.A = alip_a(mass, p.height, gravity)
        kf = KalmanFilter(dim_x=4, dim_z=4)
        kf.H = np.eye(4)
        kf.R = np.diag([p.meas_pos**2, p.meas_pos**2, p.meas_mom**2, p.meas_mom**2])
        self.kf = kf
        self._qc = np.array([p.proc_pos**2, p.proc_pos**2, p.proc_mom**2, p.proc_mom**2])
        self._dt = -1.0
        self.stance = -1
        self.x = np.zeros(4)
        #: dt (us) -> (F, Q): the laptop's packets come every few cycles, so few distinct dts
        self._discrete: dict[int, tuple[np.ndarray, np.ndarray]] = {}

    def discretise(self, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """(1) for a step ``dt``: the transition ``expm(A dt)`` and the process noise ``Q``
        (memoised per microsecond of dt: an ``expm`` costs ~50 us, a lookup ~0.1)."""
        key = round(dt * 1e6)
        exact = abs(key * 1e-6 - dt) <= 1e-12  # a whole number of microseconds: memoisable
        hit = self._discrete.get(key) if exact else None
        if hit is None:
            hit = (expm(self.A * dt), np.diag(self._qc * dt))
            if exact and len(self._discrete) < 64:
                self._discrete[key] = hit
        return hit

    def _set_dt(self, dt: float) -> None:
        """Discretise (1) for step ``dt`` (cached: the packet period rarely changes)."""
        if abs(dt - self._dt) < 1e-9:
            return
        self._dt = dt
        self.kf.F, self.kf.Q = self.discretise(dt)

    def step(self, z: np.ndarray, stance: int, dt: float) -> np.ndarray:
        """One packet: ``z`` the measured ALIP state about the ``stance`` foot; returns x."""
        kf = self.kf
        if stance != self.stance or dt <= 0.0 or dt > 0.05:
            # new stance foot (or a long gap): the state jumped, restart from the measurement
            self.stance = stance
            kf.x = z.reshape(4, 1).copy()
            kf.P = kf.R.copy()
        else:
            self._set_dt(dt)
            kf.predict()
            kf.update(z)
        self.x[:] = kf.x[:, 0]
        return self.x
