"""Test-only process: a periodic loop whose every Nth tick is too slow."""

from __future__ import annotations

import time

from lcmtypes import command_t
from runtime.node import Node


class Sleeper(Node):
    name = "sleeper"
    outputs = {"out": command_t}

    def __init__(self, every: int, sleep_s: float) -> None:
        self.every = every
        self.sleep_s = sleep_s
        self.count = 0

    def tick(self, ctx, inbox) -> None:  # type: ignore[no-untyped-def]
        msg = command_t()
        msg.header.utime = ctx.now_utime  # the tick's scheduled slot, us since the loop started
        msg.vx = float(self.count)
        ctx.publish("out", msg)
        self.count += 1
        if self.count % self.every == 0:
            time.sleep(self.sleep_s)


def make_node(proc, profile) -> Node:  # type: ignore[no-untyped-def]
    return Sleeper(int(proc.params.get("every", 20)), float(proc.params.get("sleep_s", 0.035)))
