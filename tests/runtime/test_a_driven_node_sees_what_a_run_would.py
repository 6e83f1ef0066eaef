"""runtime.driver.NodeDriver: a node ticked by hand gets its inputs through the runners' own
port buffers (newest or each, the edge checks) and its outputs are kept decoded, so a test
of a node sees what a live run or the harness would."""

from __future__ import annotations

import math

import pytest

from lcmtypes import command_t
from runtime.driver import NodeDriver
from tests.procs.echo import Echo
from tests.runtime.test_harness import Accumulator


def _cmd(utime: int, vx: float) -> command_t:
    m = command_t()
    m.header.utime, m.vx = utime, vx
    return m


def test_newest_trigger_skips_stale_messages_and_stamps_the_clock() -> None:
    d = NodeDriver(Echo(0.0))
    d.put("in", _cmd(1_000, 0.1))
    d.put("in", _cmd(2_000, 0.2))
    assert d.tick() and d.ctx.now_utime == 2_000
    assert [m.vx for m in d.sent["out"]] == [0.2]  # the newest only, as a control loop
    assert not d.tick() and d.ticks == 1  # nothing new came: no tick, as in a run


def test_each_trigger_takes_every_message_in_order() -> None:
    d = NodeDriver(Accumulator())
    for k in range(1, 4):
        d.put("in", _cmd(k, float(k)))
    while d.tick():
        pass
    assert [m.vx for m in d.sent["out"]] == [1.0, 3.0, 6.0]


def test_the_edge_checks_apply_as_in_a_run() -> None:
    d = NodeDriver(Echo(0.0), limits={"in": {"vx": (-1.0, 1.0)}})
    for k, vx in enumerate((math.nan, 5.0), start=1):
        d.put("in", _cmd(k, vx))
        assert not d.tick()  # rejected: no tick on it
    assert not d.sent["out"] and d.ports["in"].rejected == 2
    with pytest.raises(KeyError, match="no input 'state'"):
        d.put("state", _cmd(3, 0.0))
