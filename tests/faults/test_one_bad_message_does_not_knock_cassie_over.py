"""One bad message on any input of a walking stack never knocks Cassie over (issue faults 1-4).

The experiment profile's five processes walk in the deterministic harness; into their channels
go, one at a time, each of the single messages that used to crash the MPFC or latch the OSC
into safe mode: a malformed elevation map (a byte count that is no grid, resolution 0, a NaN
origin), a bit-flipped network state that still decodes, a radio command of 1e12 m/s, a NaN
plan, a NaN state, states off the clock (stale and from the future), a foothold with a NaN
vertex. Each is rejected at the edge (``runtime.validate``) and counted; no tick raises, the
OSC never leaves walking, and the robot walks on.
"""

from __future__ import annotations

import copy
import math
from typing import Any

import pytest

from lcmtypes import command_t, elevation_map_t
from runtime.config import HW_CONFIG_DIR, load_profile
from runtime.harness import Harness
from runtime.node import HEALTH_OK

pytestmark = pytest.mark.faults  # the short part of the suite: runs by default too


def _bit_flipped(msg: Any) -> bytes:
    """``msg`` encoded with one bit of its time's top byte flipped: it still decodes."""
    raw = bytearray(msg.encode())
    raw[8] ^= 0x10  # header.utime is the first field after the 8-byte fingerprint
    return bytes(raw)


def _bad_map(kind: str) -> elevation_map_t:
    m = elevation_map_t()
    m.resolution, m.rows, m.cols, m.origin = 0.04, 50, 50, [0.0, -1.0]
    m.num_layers, m.layer_names = 1, ["elevation"]
    m.data = bytes(4 * 50 * 50)
    if kind == "bytes":
        m.data = m.data[:-3]  # not a multiple of 4 (mpfc/process.py raised ValueError)
    elif kind == "resolution":
        m.resolution = 0.0
    elif kind == "origin":
        m.origin = [math.nan, 0.0]
    m.num_bytes = len(m.data)
    return m


@pytest.fixture(scope="module")
def walk() -> dict[str, Any]:
    """7 s of walking with the faults, each sent once, 0.4 s apart from 1 s on."""
    h = Harness.from_profile(load_profile(HW_CONFIG_DIR / "experiment.yaml"))
    newest: dict[str, Any] = {}
    for ch in ("NETWORK_CASSIE_STATE", "CASSIE_STATE", "NETWORK_MPFC_PLAN", "FOOTHOLDS"):
        h.tap(ch, lambda _t, m, ch=ch: newest.__setitem__(ch, m))
    modes: list[int] = []
    h.tap("OSC_TORQUE", lambda _t, m: modes.append(int(m.mode)))

    def nan_copy(ch: str, field: str, index: int) -> Any:
        m = copy.deepcopy(newest[ch])
        vals = list(getattr(m, field))
        if isinstance(vals[index], list):
            vals[index] = [math.nan, *vals[index][1:]]
        else:
            vals[index] = math.nan
        setattr(m, field, vals)
        return m

    def clock(ch: str, dt_s: float) -> Any:
        m = copy.deepcopy(newest[ch])
        m.header.utime += round(dt_s * 1e6)
        return m

    def command() -> command_t:
        c = command_t()
        c.vx, c.vy, c.mode = 1e12, 0.0, 0
        return c

    def nan_vertex() -> Any:
        m = copy.deepcopy(newest["FOOTHOLDS"])
        m.footholds[0].vertices[0] = [math.nan, 0.0, 0.0]
        return m

    faults = [
        ("ELEVATION_MAP", lambda: _bad_map("bytes")),
        ("ELEVATION_MAP", lambda: _bad_map("resolution")),
        ("ELEVATION_MAP", lambda: _bad_map("origin")),
        ("NETWORK_CASSIE_STATE", lambda: _bit_flipped(newest["NETWORK_CASSIE_STATE"])),
        ("COMMAND", command),
        ("NETWORK_MPFC_PLAN", lambda: nan_copy("NETWORK_MPFC_PLAN", "stance_foot_world", 0)),
        ("CASSIE_STATE", lambda: nan_copy("CASSIE_STATE", "q", 2)),
        ("CASSIE_STATE", lambda: clock("CASSIE_STATE", -3.0)),
        ("CASSIE_STATE", lambda: clock("CASSIE_STATE", +5.0)),
        ("FOOTHOLDS", nan_vertex),
    ]
    t_us = 1_000_000
    for channel, make in faults:
        h.run_until(t_us)
        h.inject(channel, make())
        t_us += 400_000
    h.run_until(7_000_000)
    nodes = {b.node.name: (i, b.node) for i, b in enumerate(h.bindings)}
    h.close()
    return {"h": h, "nodes": nodes, "modes": modes}


def test_no_fault_message_knocks_the_robot_over(walk):
    sim = walk["nodes"]["sim"][1]
    assert sim.health() == HEALTH_OK, sim.status()
    assert sim.counters()["walked_m"] > 1.5  # 0.375 m/s for ~6 s after the release


def test_the_osc_never_leaves_walking_and_no_tick_raises(walk):
    modes = walk["modes"]
    first_walk = modes.index(0)
    assert set(modes[first_walk:]) == {0}, "the OSC left walking"
    assert all(g.errors == 0 for g in walk["h"].guards), [g.last_error for g in walk["h"].guards]


def test_every_fault_is_rejected_at_the_edge_and_counted(walk):
    h, nodes = walk["h"], walk["nodes"]
    mpfc, osc = nodes["mpfc"][0], nodes["osc"][0]
    rejected = {(name, role): p.rejected for name, (i, _) in nodes.items()
                for role, p in h._ports[i].items()}
    assert rejected[("mpfc", "elevation_map")] == 3
    assert rejected[("mpfc", "state")] == 1
    assert rejected[("mpfc", "command")] == 1
    assert rejected[("mpfc", "footholds")] == 1
    assert rejected[("osc", "plan")] == 1
    assert rejected[("osc", "command")] == 1
    assert rejected[("osc", "state")] == 3
    assert mpfc != osc
