"""Test scaffolding for the sim: a real in-process Context/Inbox pair that drives a Node tick by
tick (the same contract the live runner and the harness implement), and common builders."""

from __future__ import annotations

import os
from collections import defaultdict
from pathlib import Path
from typing import Any

import pytest

os.environ.setdefault("MENAGERIE_ROOT", "/work/shared/menagerie")

from runtime.config_types import ProcessConfig, Profile

REPO = Path(__file__).resolve().parents[2]
HW_CONFIG = REPO / "hw_config"


class Driver:
    """Calls ``node.tick`` with chosen inputs and records everything the node publishes."""

    def __init__(self, node: Any) -> None:
        self.node = node
        self.now_utime = 0
        self.published: dict[str, list[Any]] = defaultdict(list)
        self._latest: dict[str, Any] = {}
        self._fresh: set[str] = set()
        self._trigger: Any | None = None
        self._queue: dict[str, list[Any]] = defaultdict(list)
        node.setup(self)

    # Context
    def due(self, role: str) -> bool:  # no decimation outside the runners
        return True

    def publish(self, role: str, msg: Any) -> None:
        assert role in self.node.outputs, role
        # raw packets are copied (the sim publishes its reused packet buffer), LCM encoded
        self.published[role].append(bytes(msg) if isinstance(msg, (bytes, bytearray))
                                    else msg.encode())

    # Inbox
    def latest(self, role: str) -> Any | None:
        return self._latest.get(role)

    def is_fresh(self, role: str) -> bool:
        return role in self._fresh

    def trigger(self) -> Any | None:
        return self._trigger

    def pop(self, role: str) -> Any | None:
        q = self._queue.get(role)
        return q.pop(0) if q else None

    def tick(self, command: bytes | None = None) -> None:
        """One tick; ``command`` arrives just before it (and triggers it if message-driven)."""
        if command is not None:
            self._latest["command"] = command
            self._fresh.add("command")
            self._queue["command"].append(command)
        self._trigger = command if self.node.trigger_role == "command" else None
        self.node.tick(self, self)
        self._fresh.clear()
        self._queue.clear()
        if self.node.period_s and self.node.trigger_role is None:
            self.now_utime += round(self.node.period_s * 1e6)


def make_proc(params: dict[str, Any] | None = None, gains: Path | None = None) -> ProcessConfig:
    """The sim's process config; ``gains`` default hw_config/gains/sim.yaml (its values are
    the defaults of every key)."""
    return ProcessConfig(name="sim", host="target", module="sim.process",
                         source_file=HW_CONFIG / "processes.yaml", rate_hz=2000.0,
                         params=params or {}, gains_file=gains or HW_CONFIG / "gains" / "sim.yaml")


def make_profile(mode: str) -> Profile:
    return Profile(name=f"test-{mode}", path=HW_CONFIG / "profiles" / "test.yaml",
                   hw_config_dir=HW_CONFIG, mode=mode, lcm_url="udpm://239.255.76.67:7667?ttl=0",
                   hosts={}, channels={}, processes={}, launch=())  # type: ignore[arg-type]


@pytest.fixture
def driver_factory():
    """Build a sim node from params/gains under a mode and wrap it in a Driver; closes nodes."""
    from runtime.builder import build_node

    made: list[Any] = []

    def build(mode: str, params: dict[str, Any] | None = None, gains: Path | None = None
              ) -> Driver:
        node = build_node(make_proc(params, gains), make_profile(mode))
        made.append(node)
        return Driver(node)

    yield build
    for n in made:
        n.close()
