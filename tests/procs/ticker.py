"""Test-only process: publishes a counter periodically; can leave a grandchild behind."""

from __future__ import annotations

import subprocess
from pathlib import Path

from lcmtypes import command_t
from runtime.node import Node


class Ticker(Node):
    name = "ticker"
    outputs = {"out": command_t}

    def __init__(self, grandchild_pid_file: str | None) -> None:
        self.count = 0
        self.grandchild_pid_file = grandchild_pid_file
        self.grandchild: subprocess.Popen[bytes] | None = None

    def setup(self, ctx) -> None:  # type: ignore[no-untyped-def]
        if self.grandchild_pid_file:
            # A grandchild in the same process group: the supervisor must not orphan it.
            self.grandchild = subprocess.Popen(["sleep", "600"])
            Path(self.grandchild_pid_file).write_text(str(self.grandchild.pid))

    def tick(self, ctx, inbox) -> None:  # type: ignore[no-untyped-def]
        msg = command_t()
        msg.header.utime = ctx.now_utime
        msg.vx = float(self.count)
        self.count += 1
        ctx.publish("out", msg)


def make_node(proc, profile) -> Node:  # type: ignore[no-untyped-def]
    return Ticker(proc.params.get("grandchild_pid_file"))
