"""The deterministic harness steps the same node objects in sim-time order, reproducibly."""

from __future__ import annotations

import time

from lcmtypes import command_t
from runtime.harness import Binding, Harness
from runtime.node import Node
from tests.procs.echo import Echo
from tests.procs.ticker import Ticker


class Accumulator(Node):
    """Integrates every message it gets (policy 'each'), publishing the running sum."""

    name = "acc"
    inputs = {"in": command_t}
    outputs = {"out": command_t}
    trigger_role = "in"
    trigger_policy = "each"

    def __init__(self) -> None:
        self.total = 0.0

    def tick(self, ctx, inbox) -> None:  # type: ignore[no-untyped-def]
        msg = inbox.trigger()
        self.total += msg.vx
        out = command_t()
        out.header.utime = msg.header.utime
        out.vx = self.total
        ctx.publish("out", out)


def _run(delay_us: int = 0, slow: bool = False) -> list[tuple[int, int, float, float]]:
    ticker = Ticker(None)
    ticker.period_s = 0.005
    echo = Echo(sleep_s=0.002 if slow else 0.0)
    h = Harness(
        [
            Binding(ticker, inputs={}, outputs={"out": "TICK"}),
            Binding(echo, inputs={"in": "TICK"}, outputs={"out": "ECHO"}, delay_us=delay_us),
            Binding(Accumulator(), inputs={"in": "ECHO"}, outputs={"out": "SUM"}),
        ]
    )
    log: list[tuple[int, int, float, float]] = []
    h.tap("ECHO", lambda t, m: log.append((t, m.header.utime, m.vx, m.vy)))
    sums: list[float] = []
    h.tap("SUM", lambda t, m: sums.append(m.vx))
    h.run_until(1_000_000)
    h.close()
    assert sums[-1] == sum(x[2] for x in log)  # 'each' saw every echo, in order
    return log


def test_harness_is_deterministic_however_slow_the_nodes_are():
    t0 = time.perf_counter()
    fast = _run()
    t_fast = time.perf_counter() - t0
    slow = _run(slow=True)  # each echo tick burns 2 ms of wall time: results must not change
    assert fast == slow
    assert len(fast) == 201  # ticks at 0, 5, ..., 1000 ms of sim time
    assert t_fast < 5.0


def test_messages_arrive_at_the_sim_time_they_were_sent_plus_modelled_delay():
    log = _run()
    for t, utime, vx, _seq in log:
        assert t == utime == int(vx) * 5000  # the echo ran at the tick's own sim time
    delayed = _run(delay_us=1500)
    assert [t - u for t, u, *_ in delayed] == [1500] * len(delayed)
    # the echo of the last tick (at 1000 ms) lands at 1001.5 ms, past the horizon
    assert [x[2] for x in delayed] == [x[2] for x in log][:-1]


def test_harness_builds_the_same_processes_as_a_launch_profile():
    from runtime.config import load_profile
    from tests.conftest import PROFILES

    profile = load_profile(PROFILES / "runtime.yaml")
    h = Harness.from_profile(profile)  # ticker (periodic, 200 Hz) -> echo (message-driven)
    echoes: list[tuple[int, float]] = []
    h.tap("TEST_ECHO", lambda t, m: echoes.append((t, m.vx)))
    h.run_until(100_000)
    h.close()
    assert [t for t, _ in echoes] == list(range(0, 100_001, 5000))
    assert [v for _, v in echoes] == [float(i) for i in range(21)]


def test_zero_delay_message_cycle_is_reported_not_hung():
    class PingPong(Node):
        inputs = {"in": command_t}
        outputs = {"out": command_t}
        trigger_role = "in"

        def setup(self, ctx) -> None:  # type: ignore[no-untyped-def]
            ctx.publish("out", command_t())

        def tick(self, ctx, inbox) -> None:  # type: ignore[no-untyped-def]
            ctx.publish("out", command_t())

    import pytest

    a, b = PingPong(), PingPong()
    a.name, b.name = "a", "b"
    h = Harness([Binding(a, {"in": "B"}, {"out": "A"}), Binding(b, {"in": "A"}, {"out": "B"})])
    with pytest.raises(RuntimeError, match="no progress in sim time"):
        h.run_until(1000)


def test_a_run_reports_its_sim_time_to_a_progress_callback_without_changing_the_result():
    """A tool's progress bar gets the sim time every 0.1 s of it and at the end; the run is
    the same as one without the callback."""
    def run(progress):  # type: ignore[no-untyped-def]
        ticker = Ticker(None)
        ticker.period_s = 0.005
        h = Harness([Binding(ticker, inputs={}, outputs={"out": "TICK"}),
                     Binding(Echo(sleep_s=0.0), inputs={"in": "TICK"}, outputs={"out": "ECHO"})])
        log: list[tuple[int, float]] = []
        h.tap("ECHO", lambda t, m: log.append((t, m.vx)))
        h.run_until(1_000_000, progress=progress)
        h.close()
        return log

    seen: list[int] = []
    assert run(seen.append) == run(None)
    assert seen == [k * 100_000 for k in range(1, 11)] + [1_000_000]
