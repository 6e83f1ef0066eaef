"""Hop latencies measured from headers: the same ``utime`` (or sequence number) on two channels.

Every message carries the ``utime`` of the robot state it was computed from and its monotonic
send time, so the latency of a hop (say state -> OSC torque) is the difference of the two send
times of the messages with the same ``utime``. Sources are remembered in bounded tables (oldest
forgotten first), so a destination that never arrives costs nothing but one table slot.
"""

from __future__ import annotations

import numpy as np


class KeyTable:
    """A bounded map from an integer key (utime or seq) to an integer value, oldest evicted."""

    def __init__(self, capacity: int) -> None:
        self.capacity = capacity
        self._d: dict[int, int] = {}

    def add(self, keys: np.ndarray, values: np.ndarray) -> None:
        """Remember ``keys[i] -> values[i]``; a repeated key keeps its first value."""
        d = self._d
        for k, v in zip(keys.tolist(), values.tolist(), strict=True):
            d.setdefault(k, v)
        excess = len(d) - self.capacity
        if excess > 0:
            for k in list(d)[:excess]:  # dicts iterate in insertion order: oldest first
                del d[k]

    def lookup(self, keys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(found mask, values with 0 where not found) for ``keys``."""
        d = self._d
        vals = [d.get(k) for k in keys.tolist()]
        found = np.array([v is not None for v in vals], dtype=bool)
        out = np.array([v if v is not None else 0 for v in vals], dtype=np.int64)
        return found, out

    def __len__(self) -> int:
        return len(self._d)


def hop_latency_ms(
    table: KeyTable, keys: np.ndarray, dest_mono_ns: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """(found mask, latency in ms of the found ones): destination send time - source send time."""
    found, src = table.lookup(keys)
    lat = (dest_mono_ns[found] - src[found]).astype(np.float64) * 1e-6
    return found, lat
