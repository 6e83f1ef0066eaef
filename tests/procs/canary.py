"""Test-only process: a periodic loop that does nothing, to show what the machine itself does
to a loop's timing (VM stalls, preemption) beside the stack, in the same run."""

from __future__ import annotations

from runtime.node import Node


class Canary(Node):
    name = "canary"

    def tick(self, ctx, inbox) -> None:  # type: ignore[no-untyped-def]
        pass


def make_node(proc, profile) -> Node:  # type: ignore[no-untyped-def]
    return Canary()
