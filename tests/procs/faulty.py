"""Test-only process: ticks, and after ``fault_after`` ticks reports a fault (a controller that
went to safe mode, a robot that fell) while staying alive."""

from __future__ import annotations

from lcmtypes import command_t
from runtime.node import HEALTH_FAULT, HEALTH_OK, Node


class Faulty(Node):
    name = "faulty"
    outputs = {"out": command_t}

    def __init__(self, fault_after: int) -> None:
        self.fault_after = fault_after
        self.count = 0

    def tick(self, ctx, inbox) -> None:  # type: ignore[no-untyped-def]
        self.count += 1
        ctx.publish("out", command_t())

    def health(self) -> int:
        return HEALTH_FAULT if self.count >= self.fault_after else HEALTH_OK

    def status(self) -> str:
        return "fell over on purpose" if self.count >= self.fault_after else "fine"

    def counters(self) -> dict[str, float]:
        return {"ticks": self.count}


def make_node(proc, profile) -> Node:  # type: ignore[no-untyped-def]
    return Faulty(int(proc.params.get("fault_after", 100)))
