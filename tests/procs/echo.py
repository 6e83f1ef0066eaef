"""Test-only process: echoes the newest message it got, optionally slowly."""

from __future__ import annotations

import time

from lcmtypes import command_t
from runtime.node import Node


class Echo(Node):
    name = "echo"
    inputs = {"in": command_t}
    outputs = {"out": command_t}
    trigger_role = "in"

    def __init__(self, sleep_s: float) -> None:
        self.sleep_s = sleep_s

    def tick(self, ctx, inbox) -> None:  # type: ignore[no-untyped-def]
        got = inbox.trigger()
        if self.sleep_s:
            time.sleep(self.sleep_s)  # a deliberately slow subscriber
        out = command_t()
        out.header.utime = got.header.utime
        out.vx = got.vx
        out.vy = float(got.header.seq)
        ctx.publish("out", out)


def make_node(proc, profile) -> Node:  # type: ignore[no-untyped-def]
    return Echo(float(proc.params.get("sleep_s", 0.0)))
