"""Test-only process: starts, publishes once, then exits with an error."""

from __future__ import annotations

import sys
import time

from lcmtypes import command_t
from runtime.bus import Bus


def main(proc, profile) -> int:  # type: ignore[no-untyped-def]
    bus = Bus(profile.lcm_url, source=proc.name)
    bus.publish(proc.outputs["out"].name, command_t())
    time.sleep(float(proc.params.get("after_s", 0.2)))
    print("crasher: failing on purpose", file=sys.stderr)
    return 3
