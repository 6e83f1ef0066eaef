"""runtime.driver.NodeDriver: a node ticked by hand gets its inputs through the runners' own
port buffers (newest or each, the edge checks) and its outputs are kept decoded, so a test
of a node sees what a live run or the harness would."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from lcmtypes import command_t
from runtime.config_types import ProcessConfig, Profile
from runtime.driver import NodeDriver
from runtime.node import Node
from tests.procs.echo import Echo
from tests.procs.ticker import Ticker
from tests.runtime.test_harness import Accumulator


def _profile() -> Profile:
    return Profile(name="test", path=Path("test.yaml"), hw_config_dir=Path("hw_config"),
                   mode="lockstep", lcm_url="udpm://239.255.76.67:7667?ttl=0", hosts={},
                   channels={}, processes={}, launch=())


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


def test_inputs_put_with_the_tick_and_outputs_kept_as_wire_bytes() -> None:
    d = NodeDriver(Accumulator(), encoded=True)
    assert d.tick(**{"in": _cmd(1, 0.5)}) and not d.tick()
    (raw,) = d.sent["out"]
    assert isinstance(raw, bytes) and command_t.decode(raw).vx == 0.5
    assert d.tick_ns > 0 and d.tick_cpu_ns >= 0  # the node's tick alone, timed


def test_a_periodic_node_ticks_at_each_period_as_in_the_harness() -> None:
    node = Ticker(None)
    node.period_s = 0.005
    d = NodeDriver(node)
    for _ in range(3):
        assert d.tick()
    assert d.tick(utime=20_000) and d.tick()  # a jump (skipped slots), then on from there
    assert [m.header.utime for m in d.sent["out"]] == [0, 5_000, 10_000, 20_000, 25_000]


class _Filler(Node):
    """Ticks on ``in``; with no trigger (a timeout or a fill), says whether ``side`` is new."""

    name = "filler"
    inputs = {"in": command_t, "side": command_t}
    outputs = {"out": command_t}
    trigger_role = "in"
    off_slot_wake = {"side": 1000.0}

    def tick(self, ctx, inbox) -> None:  # type: ignore[no-untyped-def]
        out = command_t()
        out.vx = -1.0 if inbox.trigger() is None else inbox.trigger().vx
        out.vy = float(inbox.is_fresh("side"))
        ctx.publish("out", out)


def test_timeout_and_fill_ticks_have_no_trigger_and_a_fill_answers_its_input() -> None:
    d = NodeDriver(_Filler())
    d.timeout_tick()
    assert not d.fill_tick()  # nothing new on the fill input: no tick
    assert d.fill_tick(side=_cmd(5, 0.0))
    assert not d.fill_tick()  # answered: the runner marks it so
    assert [(m.vx, m.vy) for m in d.sent["out"]] == [(-1.0, 0.0), (-1.0, 1.0)]
    with pytest.raises(ValueError, match="off_slot_wake"):
        NodeDriver(Echo(0.0)).fill_tick()


def test_from_config_builds_the_node_with_its_limits_and_output_rates() -> None:
    proc = ProcessConfig(name="echo", host="nuc", module="tests.procs.echo",
                         source_file=Path("processes.yaml"), limits={"in": {"vx": (-1.0, 1.0)}},
                         output_rate_hz={"out": 1000.0})
    d = NodeDriver.from_config(proc, _profile())
    for utime, vx in ((1_000, 0.1), (1_500, 0.2), (2_000, 5.0), (2_100, 0.3)):
        d.tick(**{"in": _cmd(utime, vx)})
    # 1_500 falls in the 1 kHz slot of 1_000 (decimated), 5.0 is over the limit (rejected)
    assert [m.vx for m in d.sent["out"]] == [0.1, 0.3] and d.ports["in"].rejected == 1
