"""A message-driven node's ``trigger_timeout_s`` (its watchdog) works in the deterministic
harness as it does live, counted in sim time: ticks with no trigger while its input is
silent, none while it is not."""

from __future__ import annotations

from lcmtypes import command_t
from runtime.harness import Binding, Harness
from runtime.node import Node


class Burst(Node):
    """Publishes every period until ``stop_us`` of sim time, then falls silent."""

    name = "burst"
    outputs = {"out": command_t}

    def __init__(self, stop_us: int) -> None:
        self.stop_us = stop_us

    def tick(self, ctx, inbox) -> None:  # type: ignore[no-untyped-def]
        if ctx.now_utime < self.stop_us:
            msg = command_t()
            msg.header.utime = ctx.now_utime
            ctx.publish("out", msg)


class Watchdog(Node):
    """Records when it ticked and whether on a message or on its timeout."""

    name = "watchdog"
    inputs = {"in": command_t}
    trigger_role = "in"
    trigger_timeout_s = 0.010

    def __init__(self) -> None:
        self.ticks: list[tuple[int, bool]] = []

    def tick(self, ctx, inbox) -> None:  # type: ignore[no-untyped-def]
        self.ticks.append((ctx.now_utime, inbox.trigger() is not None))


def test_timeout_ticks_come_every_timeout_of_silence_and_never_while_messages_flow() -> None:
    burst, dog = Burst(stop_us=50_000), Watchdog()
    burst.period_s = 0.005
    h = Harness([Binding(burst, inputs={}, outputs={"out": "IN"}),
                 Binding(dog, inputs={"in": "IN"}, outputs={})])
    h.run_until(100_000)
    h.close()
    on_message = [t for t, m in dog.ticks if m]
    on_timeout = [t for t, m in dog.ticks if not m]
    assert on_message == list(range(0, 50_000, 5_000))
    # the last message at 45 ms; then one tick per 10 ms of silence, up to 100 ms
    assert on_timeout == [55_000, 65_000, 75_000, 85_000, 95_000]
