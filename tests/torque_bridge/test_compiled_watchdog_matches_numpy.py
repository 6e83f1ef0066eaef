"""The bridge's compiled command check and watchdog/clamp give what its numpy code did, bit
for bit, through valid, NaN/inf and wrong-length commands, silences that trip the watchdog,
commands from the future, clamps, and NaN motor velocities, with either fallback."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from processes.torque_bridge.bridge import (
    SOURCE_COMMAND,
    SOURCE_REJECTED,
    SOURCE_WATCHDOG_DAMPING,
    SOURCE_WATCHDOG_ZERO,
    BridgeParams,
    TorqueBridge,
)
from runtime.cassie_packets import NUM_MOTORS, InputPacket


class NumpyBridge:
    """TorqueBridge.on_command and step as they were written with numpy (reference)."""

    def __init__(self, p: BridgeParams) -> None:
        self.params = p
        self.limit = np.array(p.torque_limit, dtype=float)
        self.kd = np.array(p.damping_kd, dtype=float)
        self.watchdog_us = round(p.watchdog_s * 1e6)
        self.command = np.zeros(NUM_MOTORS)
        self.commanded = np.zeros(NUM_MOTORS)
        self.torque = np.zeros(NUM_MOTORS)
        self.command_utime: int | None = None
        self.rejected_pending = False
        self.source = SOURCE_WATCHDOG_ZERO
        self.age_ms = float("inf")
        self.watchdog_trips = self.clamp_count = self.nan_rejects = 0
        self.last_reason = "no command yet"
        self._tripped = True

    def on_command(self, torque: Any, utime: int) -> bool:
        t = np.asarray(torque, dtype=float)
        if t.shape != (NUM_MOTORS,):
            self.nan_rejects += 1
            self.rejected_pending = True
            self.last_reason = f"command has {t.size} torques, expected {NUM_MOTORS}"
            return False
        self.commanded[:] = t
        if not np.isfinite(t).all():
            self.nan_rejects += 1
            self.rejected_pending = True
            self.last_reason = "command holds NaN or inf"
            return False
        self.command[:] = t
        self.command_utime = int(utime)
        self.rejected_pending = False
        return True

    def step(self, now_utime: int, motor_vel: np.ndarray) -> np.ndarray:
        p, cu = self.params, self.command_utime
        self.age_ms = float("inf") if cu is None else (now_utime - cu) / 1000.0
        # which case: a rejected command pending, a fresh one, none yet, or a stale one
        case = ("rejected" if self.rejected_pending
                else "none" if cu is None
                else "fresh" if abs(now_utime - cu) < self.watchdog_us else "stale")
        if case == "fresh":
            self.torque[:] = self.command
            self.source, self._tripped, self.last_reason = SOURCE_COMMAND, False, "ok"
        elif case == "none":
            self.torque[:] = 0.0
            self.source = SOURCE_WATCHDOG_ZERO
        else:
            if case == "stale" and not self._tripped:
                self.watchdog_trips += 1
                self.last_reason = f"no fresh command for {p.watchdog_s * 1e3:.0f} ms"
            self._tripped = True
            self._fallback(motor_vel)
            self.source = {"rejected": SOURCE_REJECTED}.get(
                case, SOURCE_WATCHDOG_ZERO if p.fallback == "zero" else SOURCE_WATCHDOG_DAMPING)
        over = np.abs(self.torque) > self.limit
        self.clamp_count += int(over.sum())
        self.torque[:] = np.where(over, np.sign(self.torque) * self.limit, self.torque)
        return self.torque

    def _fallback(self, motor_vel: np.ndarray) -> None:
        if self.params.fallback == "damping" and np.isfinite(motor_vel).all():
            np.multiply(self.kd, motor_vel, out=self.torque)
            np.negative(self.torque, out=self.torque)
        else:
            self.torque[:] = 0.0


STATE = ("command_utime", "rejected_pending", "source", "age_ms", "watchdog_trips",
         "clamp_count", "nan_rejects", "last_reason", "_tripped")


def _same(got: TorqueBridge, want: NumpyBridge, k: int) -> None:
    for name in ("torque", "command", "commanded"):  # bytes: signed zeros and NaNs count
        assert getattr(got, name).tobytes() == getattr(want, name).tobytes(), (k, name)
    for name in STATE:
        assert getattr(got, name) == getattr(want, name), (k, name)


@pytest.mark.parametrize("fallback", ["damping", "zero"])
@pytest.mark.parametrize("as_tuple", [True, False])
def test_compiled_bridge_gives_the_numpy_torques_sources_and_counters(fallback: str,
                                                                      as_tuple: bool) -> None:
    p = BridgeParams(fallback=fallback)  # type: ignore[arg-type]
    got, want = TorqueBridge(p), NumpyBridge(p)
    pkt = InputPacket()
    rng = np.random.default_rng(5)
    limit = np.array(p.torque_limit)
    utime = 0
    sources: set[int] = set()
    for k in range(4000):
        utime += 500
        r = rng.random()
        torque: Any = None
        if k < 30 or 1500 <= k < 1560 or 2500 <= k < 2540:
            pass  # no controller yet, then two silences of 30 and 20 ms
        elif r < 0.75:
            torque = rng.normal(0.0, 0.6, NUM_MOTORS) * limit  # some over the limits
            torque[rng.random(NUM_MOTORS) < 0.05] = -0.0
        elif r < 0.85:
            torque = rng.normal(0.0, 10.0, NUM_MOTORS)
            torque[rng.integers(NUM_MOTORS)] = rng.choice([np.nan, np.inf, -np.inf])
        elif r < 0.88:
            torque = rng.normal(0.0, 10.0, rng.choice([0, 9, 11]))
        if torque is not None:
            sent = tuple(float(x) for x in torque) if as_tuple else list(torque)
            cmd_utime = utime + (int(rng.integers(-20_000, 20_000)) if r < 0.02 else 0)
            assert got.on_command(sent, cmd_utime) == want.on_command(sent, cmd_utime)
        mv = rng.normal(0.0, 30.0, NUM_MOTORS)
        if rng.random() < 0.2:
            mv[rng.integers(NUM_MOTORS)] = np.nan
        tau = got.step(utime, (lambda v=mv: v) if k % 2 else mv, out=pkt.torque)
        want.step(utime, mv)
        assert tau is got.torque and pkt.torque.tobytes() == tau.tobytes()
        _same(got, want, k)
        sources.add(got.source)
    assert sources == {SOURCE_COMMAND, SOURCE_REJECTED, SOURCE_WATCHDOG_ZERO} | (
        {SOURCE_WATCHDOG_DAMPING} if fallback == "damping" else set())
    assert got.watchdog_trips >= 2 and got.clamp_count > 100 and got.nan_rejects > 100


def test_a_tuple_that_is_not_all_floats_is_taken_like_any_sequence() -> None:
    got, want = TorqueBridge(), NumpyBridge(BridgeParams())
    mixed = (1, 2.0, 3, 4.0, 5, 6.0, 7, 8.0, 9, 10.0)
    assert got.on_command(mixed, 500) and want.on_command(mixed, 500)
    got.step(500, np.zeros(NUM_MOTORS))
    want.step(500, np.zeros(NUM_MOTORS))
    _same(got, want, 0)
