"""Test scaffolding for the sim: its node built and driven tick by tick by
``runtime.driver.NodeDriver`` (the runners' own port buffers), its outputs kept as the bytes
that go on the wire, and common builders."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import pytest

os.environ.setdefault("MENAGERIE_ROOT", "/work/shared/menagerie")

from runtime.config_types import ProcessConfig, Profile
from runtime.driver import NodeDriver

REPO = Path(__file__).resolve().parents[2]
HW_CONFIG = REPO / "hw_config"


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
    """Build a sim node from params/gains under a mode and drive it with a ``NodeDriver``
    (``d.tick(command=packet)``; ``d.timeout_tick()`` the lockstep resend timer's tick; in
    real time ``d.tick()`` steps at the next 0.5 ms slot); outputs kept encoded in
    ``d.sent[role]``. Closes the nodes."""
    made: list[Any] = []

    def build(mode: str, params: dict[str, Any] | None = None, gains: Path | None = None
              ) -> NodeDriver:
        d = NodeDriver.from_config(make_proc(params, gains), make_profile(mode), setup=False,
                                   encoded=True)
        made.append(d.node)
        d.node.setup(d.ctx)
        return d

    yield build
    for n in made:
        n.close()
