"""The runtime's edge: a message that is not finite, out of its declared ranges, inconsistent
or off its stream's clock never reaches a node; the node keeps the previous good one, a bad
trigger causes no tick, and an exception in a tick is counted, not fatal."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from lcmtypes import command_t, elevation_map_t, foothold_set_t, foothold_t, robot_state_t
from runtime.bus import Subscription
from runtime.config import load_profile
from runtime.errors import ConfigError
from runtime.harness import Binding, Harness
from runtime.node import Node
from runtime.validate import InputCheck, input_checks


def _state(utime: int = 1000) -> robot_state_t:
    s = robot_state_t()
    s.header.utime = utime
    s.num_positions, s.num_velocities, s.num_motors = 3, 2, 1
    s.q, s.v, s.motor_torque = [0.0, 0.0, 0.9], [0.1, 0.2], [0.0]
    return s


def _map(rows: int = 4, cols: int = 5, layers: int = 1) -> elevation_map_t:
    m = elevation_map_t()
    m.resolution, m.rows, m.cols, m.origin = 0.04, rows, cols, [1.0, 2.0]
    m.num_layers, m.layer_names = layers, ["elevation"] * layers
    m.data = bytes(4 * rows * cols * layers)
    m.num_bytes = len(m.data)
    return m


def test_a_nan_or_inf_anywhere_is_rejected_with_the_field_named():
    check = InputCheck(robot_state_t)
    assert check(_state()) is None
    s = _state()
    s.v = [0.0, math.nan]
    assert check(s) == "v is not finite"
    s = _state()
    s.imu_accel = [0.0, math.inf, 0.0]
    assert "imu_accel" in check(s)
    # nested structs, 2-D arrays: one NaN vertex of one foothold rejects the set
    f = foothold_t()
    f.normal, f.offset = [0.0, 0.0, 1.0], 0.0
    f.num_halfspaces, f.A, f.b = 3, [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [-1.0, -1.0, 0.0]], [1, 1, 1]
    f.num_vertices, f.vertices = 2, [[0.0, 0.0, 0.0], [math.nan, 0.0, 0.0]]
    fs = foothold_set_t()
    fs.num_footholds, fs.footholds = 1, [f]
    assert InputCheck(foothold_set_t)(fs) == "footholds: vertices is not finite"


def test_declared_ranges_reject_a_command_of_1e12_m_per_s():
    check = InputCheck(command_t, {"vx": (-1.0, 1.0), "mode": (0, 1)})
    c = command_t()
    c.vx = 0.5
    assert check(c) is None
    c.vx = 1e12
    assert "vx = 1e+12 outside [-1, 1]" in check(c)
    c.vx, c.mode = 0.0, 7
    assert "mode" in check(c)
    arr = InputCheck(robot_state_t, {"q": (-10.0, 10.0)})
    s = _state()
    s.q = [0.0, 1e200, 0.0]  # a bit flip that still decodes
    assert "q outside [-10, 10]" in arr(s)


@pytest.mark.parametrize(("change", "what"), [
    (lambda m: setattr(m, "data", m.data[:-3]), "data bytes"),
    (lambda m: setattr(m, "resolution", 0.0), "resolution"),
    (lambda m: setattr(m, "origin", [math.nan, 0.0]), "origin is not finite"),
    (lambda m: setattr(m, "rows", 0), "0 x 5"),
    (lambda m: setattr(m, "num_layers", 2), "layers"),
])
def test_an_inconsistent_elevation_map_is_rejected(change, what):
    check = InputCheck(elevation_map_t)
    m = _map()
    assert check(m) is None
    change(m)
    assert what in check(m)


def test_one_message_off_the_stream_clock_is_rejected_and_a_real_jump_resyncs():
    check = InputCheck(robot_state_t, {"utime_step_s": (0.0, 1.0)})
    assert check(_state(1_000_000)) is None
    assert check(_state(1_000_500)) is None
    assert "off its clock" in check(_state(9_000_000_000))  # a flipped bit of the time
    assert check(_state(1_001_000)) is None  # the stream goes on
    assert "off its clock" in check(_state(200_000))  # a stale replay, once
    assert check(_state(1_001_500)) is None
    # a restart of the sim: time starts again; the second message agreeing re-syncs
    assert check(_state(500)) is not None
    assert check(_state(1000)) is None
    assert check(_state(1500)) is None


def test_limits_name_their_file_and_key_when_wrong(tmp_path: Path):
    with pytest.raises(ConfigError, match=r"limits\.command\.speed") as e:
        input_checks({"command": command_t}, {"command": {"speed": (0, 1)}}, "f.yaml",
                     "processes.mpfc.limits")
    assert "vx" in str(e.value.allowed)
    with pytest.raises(ConfigError, match="not an LCM input"):
        input_checks({"command": command_t}, {"radio": {"vx": (0, 1)}}, "f.yaml")
    with pytest.raises(ConfigError, match="no header"):
        input_checks({"raw": foothold_t},
                     {"raw": {"utime_step_s": (0.0, 1.0)}}, "f.yaml")
    hw = Path(__file__).resolve().parents[2] / "hw_config"
    prof = tmp_path / "p.yaml"
    prof.write_text(f"include: [{hw / 'sim.yaml'}]\nprofile: bad\n"
                    "overrides: {mpfc: {limits: {command: {vx: [1.0, -1.0]}}}}\n")
    with pytest.raises(ConfigError, match=r"limits\.command\.vx"):
        load_profile(prof)


def test_the_port_keeps_the_previous_good_message_and_counts_the_rejection():
    port = Subscription("COMMAND", command_t, "newest", capacity=4)
    port.check = InputCheck(command_t, {"vx": (-1.0, 1.0)})
    good, bad = command_t(), command_t()
    good.vx, bad.vx = 0.3, 1e12
    port._on_message("COMMAND", good.encode())
    assert port.take().vx == 0.3
    port._on_message("COMMAND", bad.encode())
    assert port.take() is None  # a trigger: nothing good came, no tick
    assert port.latest().vx == 0.3  # an input read at a tick: the previous good one
    assert port.rejected == 1 and "vx" in port.last_rejected


class _Counter(Node):
    """Ticks on each command; raises on vx == 0.7 (a bug in an algorithm)."""

    name = "counter"
    inputs = {"command": command_t}
    outputs = {}
    trigger_role = "command"

    def __init__(self) -> None:
        self.seen: list[float] = []

    def tick(self, ctx, inbox) -> None:  # type: ignore[no-untyped-def]
        c = inbox.trigger()
        if c.vx == 0.7:
            raise ZeroDivisionError("a bug")
        self.seen.append(c.vx)


def test_in_the_harness_a_bad_trigger_causes_no_tick_and_a_raising_tick_is_counted():
    node = _Counter()
    h = Harness([Binding(node, inputs={"command": "COMMAND"}, outputs={},
                         limits={"command": {"vx": (-1.0, 1.0)}})])
    for k, vx in enumerate((0.1, 1e12, 0.7, math.nan, 0.2)):
        c = command_t()
        c.header.utime = 1000 * (k + 1)
        c.vx = vx
        h.inject("COMMAND", c, at_us=1000 * (k + 1))
    h.run_until(10_000)
    assert node.seen == [0.1, 0.2]
    assert h.guards[0].errors == 1 and "ZeroDivisionError" in h.guards[0].last_error
    port = h._ports[0]["command"]
    assert port.rejected == 2
