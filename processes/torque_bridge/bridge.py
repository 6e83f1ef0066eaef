"""The torque bridge's logic, without transport: validate, clamp, watchdog, fallback.

Watchdog clock: the *sim time of the robot state* that triggers each send. A command carries
the ``utime`` of the state it was computed from, so its age is ``state.utime - cmd.utime``: how
stale the torques are with respect to the robot they are applied to. This is deterministic
(the harness and lockstep mode give the same trips as real time), needs no wall clock, and it
still trips when the controller stops, because states keep arriving at 2 kHz. If the states
themselves stop, the bridge sends nothing and the target PC's own 10 ms watchdog zeroes the
torques. A command stamped far in the future of the state (the sim was restarted) is stale.

A command holding NaN/inf, or of the wrong length, is rejected at once (counted, reported) and
the fallback is sent until a valid command arrives: a controller producing NaN has failed, and
waiting out the watchdog with its previous torques would be worse. The fallback is zero torque
or joint damping ``tau = -kd * motor_velocity`` (configurable), clamped like any command.
Before the first valid command it is always zero torque: damping torques are non-zero
commands, and the target PC releases its start-up pelvis holder on the first of those.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numba
import numpy as np

from runtime.cassie_packets import NUM_MOTORS
from runtime.params import spec

Fallback = Literal["zero", "damping"]
MOTOR_KINDS = ("hip_roll", "hip_yaw", "hip_pitch", "knee", "foot")

# applied_input_t.source
SOURCE_COMMAND = 0
SOURCE_WATCHDOG_ZERO = 1
SOURCE_WATCHDOG_DAMPING = 2
SOURCE_REJECTED = 3
SOURCE_NAMES = ("command", "watchdog zero", "watchdog damping", "rejected command")

DEFAULT_GAINS_FILE = Path(__file__).resolve().parents[2] / "hw_config" / "gains" / (
    "torque_bridge.yaml"
)


@dataclass(frozen=True)
class BridgeParams:
    """Torque limits and watchdog settings, per motor in ``MOTOR_NAMES`` order: what
    ``TorqueBridge`` runs on (``from_gains``: the gains file's values, per motor)."""

    torque_limit: tuple[float, ...] = (112.5, 112.5, 195.2, 195.2, 45.0) * 2  # N m
    watchdog_s: float = 0.010
    fallback: Fallback = "damping"
    damping_kd: tuple[float, ...] = (5.0, 5.0, 5.0, 5.0, 1.0) * 2  # N m s/rad
    release_holder: bool = False

    @classmethod
    def from_gains(cls, gains: BridgeGains) -> BridgeParams:
        """The settings of a gains file (``BridgeGains``), each kind's value on both legs."""
        return cls(
            torque_limit=gains.torque_limit_nm.per_motor(),
            watchdog_s=gains.watchdog_ms / 1000.0,
            fallback=gains.fallback,
            damping_kd=gains.damping_kd.per_motor(),
            release_holder=gains.release_holder,
        )


_LIMIT = {"lo": 0.0, "hi": 1000.0, "lo_open": True, "unit": "N m"}
_KD = {"lo": 0.0, "hi": 1000.0, "unit": "N m s/rad"}


class _PerMotorKind:
    """A value per motor kind (the fields, named as ``MOTOR_KINDS``), the same on both legs."""

    def per_motor(self) -> tuple[float, ...]:
        """The 10 motors' values (``MOTOR_NAMES`` order: the left leg, then the right)."""
        return tuple(float(getattr(self, k)) for k in MOTOR_KINDS) * 2


@dataclass(frozen=True)
class TorqueLimits(_PerMotorKind):
    """Joint-side torque limit of each motor kind (both legs), N m; every kind is given."""

    hip_roll: float = spec(**_LIMIT)
    hip_yaw: float = spec(**_LIMIT)
    hip_pitch: float = spec(**_LIMIT)
    knee: float = spec(**_LIMIT)
    foot: float = spec(**_LIMIT)


@dataclass(frozen=True)
class DampingGains(_PerMotorKind):
    """Joint damping of the fallback, per motor kind (both legs), N m s/rad; every kind is
    given."""

    hip_roll: float = spec(**_KD)
    hip_yaw: float = spec(**_KD)
    hip_pitch: float = spec(**_KD)
    knee: float = spec(**_KD)
    foot: float = spec(**_KD)


@dataclass(frozen=True)
class BridgeGains:
    """``hw_config/gains/torque_bridge.yaml`` (the process module's ``Gains``)."""

    torque_limit_nm: TorqueLimits = spec(
        default_factory=lambda: TorqueLimits(*BridgeParams.torque_limit[:5]))
    #: no fresh command for this long (state sim time) -> fallback
    watchdog_ms: float = spec(10.0, lo=0.5, hi=1000.0, unit="ms")
    fallback: Fallback = spec("damping")
    damping_kd: DampingGains = spec(
        default_factory=lambda: DampingGains(*BridgeParams.damping_kd[:5]))
    release_holder: bool = False  # set the release flag on packets sent from a valid command


#: what ``_torques`` puts out: the newest command, zeros, or joint damping
_OUT_COMMAND, _OUT_ZERO, _OUT_DAMPING = 0, 1, 2


class TorqueBridge:
    """Keeps the newest valid command and turns each robot state into the torques to send.

    The per-command work is two compiled calls: ``on_command`` copies and checks the torques
    (``_take_command``), ``step`` picks the watchdog's case in a few integer comparisons and
    writes the clamped torques (``_torques``)."""

    def __init__(self, params: BridgeParams | None = None) -> None:
        self.params = p = params or BridgeParams()
        if len(p.torque_limit) != NUM_MOTORS or len(p.damping_kd) != NUM_MOTORS:
            raise ValueError(f"torque_limit and damping_kd need {NUM_MOTORS} values")
        self.limit = np.array(p.torque_limit, dtype=float)
        self.kd = np.array(p.damping_kd, dtype=float)
        self.watchdog_us = round(p.watchdog_s * 1e6)
        self.command = np.zeros(NUM_MOTORS)  # newest valid command, as received
        self.commanded = np.zeros(NUM_MOTORS)  # newest command, as received (even if rejected)
        self.torque = np.zeros(NUM_MOTORS)  # what goes out
        self.command_utime: int | None = None
        self.rejected_pending = False
        self.source = SOURCE_WATCHDOG_ZERO
        self.age_ms = float("inf")
        self.watchdog_trips = 0
        self.clamp_count = 0
        self.nan_rejects = 0
        self.last_reason = "no command yet"
        self._tripped = True  # no command yet counts as tripped, but not as a trip
        self._no_out = np.zeros(0)
        self._nan_vel = np.full(NUM_MOTORS, np.nan)
        _warm_kernels(self)

    def on_command(self, torque: Any, utime: int) -> bool:
        """A new command (joint-side N m, motor order) computed from the state at ``utime``.
        Returns False (and counts it) when rejected."""
        ok = None
        if type(torque) is tuple and len(torque) == NUM_MOTORS:
            try:  # a decoded message's torques, a tuple of floats: straight into the kernel
                ok = _take_command(torque, self.commanded, self.command)
            except numba.core.errors.TypingError:  # not all floats
                pass
        if ok is None:
            t = np.asarray(torque, dtype=float)
            if t.shape != (NUM_MOTORS,):
                return self._reject(f"command has {t.size} torques, expected {NUM_MOTORS}")
            ok = _take_command(t, self.commanded, self.command)
        if not ok:
            return self._reject("command holds NaN or inf")
        self.command_utime = int(utime)
        self.rejected_pending = False
        return True

    def _reject(self, reason: str) -> bool:
        """Count a rejected command; the next step falls back (``SOURCE_REJECTED``)."""
        self.nan_rejects += 1
        self.rejected_pending = True
        self.last_reason = reason
        return False

    def step(self, now_utime: int,
             motor_vel: np.ndarray | Callable[[], np.ndarray],
             out: np.ndarray | None = None) -> np.ndarray:
        """Torques to send for the robot state at ``now_utime``; updates ``source``,
        ``age_ms`` and the counters. ``motor_vel``: the motor velocities for the damping
        fallback, or a function giving them (called only when the fallback needs them).
        ``out``: also write the torques there (the packet's field)."""
        p = self.params
        cu = self.command_utime
        age_us = None if cu is None else now_utime - cu
        self.age_ms = float("inf") if age_us is None else age_us / 1000.0
        fresh = age_us is not None and -self.watchdog_us < age_us < self.watchdog_us
        if self.rejected_pending:
            kind = self._fallback_kind()
            self.source = SOURCE_REJECTED
            self._tripped = True
        elif fresh:
            kind = _OUT_COMMAND
            self.source = SOURCE_COMMAND
            self._tripped = False
            self.last_reason = "ok"
        elif cu is None:
            # no controller yet: zero torque, whatever the fallback. Damping torques here would
            # be non-zero commands, and the target PC releases its start-up holder on those.
            kind = _OUT_ZERO
            self.source = SOURCE_WATCHDOG_ZERO
        else:
            if not self._tripped:
                self.watchdog_trips += 1
                self.last_reason = f"no fresh command for {p.watchdog_s * 1e3:.0f} ms"
            self._tripped = True
            kind = self._fallback_kind()
            self.source = (SOURCE_WATCHDOG_ZERO if p.fallback == "zero"
                           else SOURCE_WATCHDOG_DAMPING)
        if kind == _OUT_DAMPING:
            mv = _motor_vel_array(motor_vel() if callable(motor_vel) else motor_vel)
        else:
            mv = self._nan_vel  # not read
        self.clamp_count += _torques(kind, self.command, self.kd, mv, self.limit, self.torque,
                                     self._no_out if out is None else out)
        return self.torque

    def _fallback_kind(self) -> int:
        return _OUT_DAMPING if self.params.fallback == "damping" else _OUT_ZERO

    def status(self) -> str:
        """One line: active source and counters."""
        return (f"{SOURCE_NAMES[self.source]}; trips {self.watchdog_trips} clamps "
                f"{self.clamp_count} rejects {self.nan_rejects}; {self.last_reason}")


@numba.njit(cache=True, nogil=True)
def _take_command(torque: Any, commanded: np.ndarray,
                  command: np.ndarray) -> bool:  # pragma: no cover
    """``commanded[:] = torque``; when every torque is finite also ``command[:] = torque``
    and True, else False (``command`` untouched)."""
    ok = True
    for i in range(commanded.shape[0]):
        t = torque[i]
        commanded[i] = t
        if not np.isfinite(t):
            ok = False
    if ok:
        for i in range(command.shape[0]):
            command[i] = commanded[i]
    return ok


@numba.njit(cache=True, nogil=True)
def _torques(kind: int, command: np.ndarray, kd: np.ndarray, motor_vel: np.ndarray,
             limit: np.ndarray, torque: np.ndarray, out: np.ndarray) -> int:  # pragma: no cover
    """``torque`` = the command (``_OUT_COMMAND``), zeros (``_OUT_ZERO``) or joint damping
    ``-(kd * motor_vel)`` (``_OUT_DAMPING``; zeros when a velocity is not finite), each then
    clipped to +-``limit``; copied into ``out`` unless it is empty. Returns how many torques
    were clipped."""
    n = torque.shape[0]
    if kind == _OUT_DAMPING:
        for i in range(n):
            if not np.isfinite(motor_vel[i]):
                kind = _OUT_ZERO
    clipped = 0
    for i in range(n):
        if kind == _OUT_COMMAND:
            t = command[i]
        elif kind == _OUT_DAMPING:
            t = -(kd[i] * motor_vel[i])
        else:
            t = 0.0
        lim = limit[i]
        if t > lim:
            t = lim
            clipped += 1
        elif t < -lim:
            t = -lim
            clipped += 1
        torque[i] = t
    if out.shape[0]:
        for i in range(n):
            out[i] = torque[i]
    return clipped


def _motor_vel_array(mv: Any) -> np.ndarray:
    """The damping fallback's motor velocities as the kernel takes them (a read-only view when
    broadcast: a type of its own for numba, so ``_warm_kernels`` makes it this same way)."""
    return np.ascontiguousarray(np.broadcast_to(np.asarray(mv, dtype=float), (NUM_MOTORS,)))


def _warm_kernels(b: TorqueBridge) -> None:
    """Compile (or load from numba's cache) the kernels for the arguments the node passes
    (a decoded message's tuple, arrays, a packet's field), before the first command."""
    from runtime.cassie_packets import InputPacket

    scratch = np.zeros(NUM_MOTORS)
    _take_command((0.0,) * NUM_MOTORS, scratch, scratch.copy())
    _take_command(scratch, scratch.copy(), scratch.copy())
    for out in (b._no_out, InputPacket().torque):
        _torques(_OUT_ZERO, scratch, b.kd, b._nan_vel, b.limit, scratch.copy(), out)
        # the damping fallback's velocities (measured on a cold cache: its first watchdog
        # trip compiled this signature for 0.2 s, in the live stack, as the holder let go)
        _torques(_OUT_DAMPING, scratch, b.kd, _motor_vel_array(scratch), b.limit,
                 scratch.copy(), out)
