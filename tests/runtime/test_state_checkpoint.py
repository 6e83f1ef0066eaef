"""A node's state saved in shared memory is loaded back exactly, and a writer killed in the
middle of a save leaves the previous save to load (runtime.checkpoint)."""

from __future__ import annotations

import numpy as np

from runtime.checkpoint import StateCheckpoint


def test_a_saved_state_loads_back_into_a_successors_arrays(tmp_path):
    s, n = np.arange(544.0), np.arange(20, dtype=np.int64)
    ck = StateCheckpoint(tmp_path / "x.state", [s, n])
    ck.save()
    s2, n2 = np.zeros(544), np.zeros(20, dtype=np.int64)
    assert StateCheckpoint(tmp_path / "x.state", [s2, n2]).load()
    np.testing.assert_array_equal(s2, s)
    np.testing.assert_array_equal(n2, n)


def test_a_save_cut_short_leaves_the_one_before(tmp_path):
    s = np.zeros(8)
    ck = StateCheckpoint(tmp_path / "x.state", [s])
    s[:] = 1.0
    ck.save()
    s[:] = 2.0
    ck.save()
    s[:] = 3.0
    ck._seq[(ck._counter + 1) & 1][0] = 0  # the next save dies after zeroing its slot...
    ck._payload[(ck._counter + 1) & 1][:16] = 0xFF  # ... and half-writing it
    out = np.zeros(8)
    assert StateCheckpoint(tmp_path / "x.state", [out]).load()
    np.testing.assert_array_equal(out, np.full(8, 2.0))


def test_nothing_saved_loads_nothing(tmp_path):
    out = np.full(4, 7.0)
    assert not StateCheckpoint(tmp_path / "y.state", [out]).load()
    np.testing.assert_array_equal(out, np.full(4, 7.0))
