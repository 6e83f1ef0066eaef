"""A node's algorithm state in shared memory, so that its successor carries on from it.

A process that is killed mid-walk and replaced (by its standby, or by a restart) starts its
algorithm from scratch; for the state estimator that meant a pose back at the origin, zero
velocity and no contact while Cassie walked on, and a fall 1.5 s later (measured). A node
that lists the arrays holding its whole state (``Node.state_arrays``) gets them copied after
every tick into a file in ``/dev/shm`` (a memory map: a memcpy, no system call; ~4.5 KB for
the estimator, 2.6 us of CPU a save here, ~0.5 % of a core at 2 kHz); its successor in the
same launch loads them before its first tick.

Two slots, written in turn: a slot's sequence number is zeroed before its payload is written
and set after, so a writer killed mid-copy leaves the other slot as the newest valid one.
The file is named after the launch's pairing token, so another launch never loads it.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from runtime.pairing import TOKEN_ENV

#: where a launch keeps its files in shared memory; ``$CASSIE_SHM_DIR`` moves it (tests give
#: each launch a folder of its own there, so they can tell what it left behind)
SHM_ENV = "CASSIE_SHM_DIR"


def shm_dir() -> Path:
    """The folder of a launch's shared-memory files (``/dev/shm`` unless ``$CASSIE_SHM_DIR``)."""
    return Path(os.environ.get(SHM_ENV) or "/dev/shm")


def checkpoint_path(process: str) -> Path | None:
    """Where ``process`` keeps its state in this launch; None outside a supervised launch
    (no token: nothing to carry on from)."""
    token = os.environ.get(TOKEN_ENV)
    if token is None or not shm_dir().is_dir():
        return None
    return shm_dir() / f"cassie-{token}-{process}.state"


def remove_checkpoints(token: int | str) -> None:
    """Delete a launch's files in shared memory (the supervisor, at shutdown): its state
    checkpoints and its succession locks (``runtime.succession``)."""
    for p in shm_dir().glob(f"cassie-{token}-*"):
        try:
            p.unlink()
        except OSError:
            pass


class StateCheckpoint:
    """Saves ``arrays`` (their bytes, in order) to ``path`` and loads them back in place."""

    def __init__(self, path: Path, arrays: list[np.ndarray]) -> None:
        if not all(a.flags.c_contiguous for a in arrays):
            raise ValueError("a node's state arrays must be contiguous (they are copied as bytes)")
        self.path = path
        size = sum(a.nbytes for a in arrays)
        slot = 8 + size  # int64 sequence number, then the payload
        if not path.exists() or path.stat().st_size != 2 * slot:
            with open(path, "wb") as f:
                f.truncate(2 * slot)
        self._map = np.memmap(path, dtype=np.uint8, mode="r+", shape=(2 * slot,))
        self._seq = [self._map[k * slot:k * slot + 8].view(np.int64) for k in (0, 1)]
        self._payload = [self._map[k * slot + 8:(k + 1) * slot] for k in (0, 1)]
        views = [a.reshape(-1).view(np.uint8) for a in arrays]
        ends = np.cumsum([0] + [v.size for v in views])
        #: per slot, (its part of the payload, the array's bytes): made once, not per save
        self._parts = [[(self._payload[k][ends[i]:ends[i + 1]], v) for i, v in enumerate(views)]
                       for k in (0, 1)]
        self._counter = max(int(self._seq[0][0]), int(self._seq[1][0]))

    def save(self) -> None:
        """Copy the arrays into the older slot, then mark it the newest."""
        self._counter += 1
        k = self._counter & 1
        seq = self._seq[k]
        seq[0] = 0
        for dst, src in self._parts[k]:
            np.copyto(dst, src)
        seq[0] = self._counter

    def remove(self) -> None:
        """Delete the file (the launch is over: no successor will load it)."""
        try:
            self.path.unlink()
        except OSError:
            pass

    def load(self) -> bool:
        """Copy the newest valid slot into the arrays; False when there is none."""
        s0, s1 = int(self._seq[0][0]), int(self._seq[1][0])
        if s0 <= 0 and s1 <= 0:
            return False
        for src, dst in self._parts[0 if s0 > s1 else 1]:
            np.copyto(dst, src)
        return True
