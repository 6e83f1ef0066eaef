"""The C++ example process (``tools/cpp_example/heading_hold.cpp``), built against the
stack's generated C++ types (``cassie types --cpp``) and LCM's own library, hears states on
a real LCM bus and answers with the stack's velocity commands: forward, turning against the
heading, at 10 Hz of robot time."""

from __future__ import annotations

import math
import shutil
import subprocess
import time
from pathlib import Path

import pytest

from lcmtypes import command_t, robot_state_t
from runtime.bus import Bus
from tools.types import build_cpp, lcm_include_and_lib

pytestmark = pytest.mark.skipif(shutil.which("g++") is None, reason="needs a C++ compiler")

SOURCE = Path(__file__).parents[2] / "tools" / "cpp_example" / "heading_hold.cpp"


def build(tmp_path: Path) -> Path:
    inc, lib = lcm_include_and_lib()
    exe = tmp_path / "heading_hold"
    subprocess.run(["g++", "-std=c++17", "-O2", "-Wall", "-Wextra", "-Werror", str(SOURCE),
                    f"-I{build_cpp(tmp_path / 'types')}", f"-I{inc}", f"-L{lib}", "-llcm",
                    f"-Wl,-rpath,{lib}", "-o", str(exe)], check=True)
    return exe


def state(utime: int, yaw: float) -> robot_state_t:
    s = robot_state_t()
    s.header.utime = utime
    s.num_positions, s.num_velocities = 35, 32
    s.q = [0.0] * 35
    s.q[2] = 1.0
    s.q[3], s.q[6] = math.cos(yaw / 2), math.sin(yaw / 2)  # w, z: a turn about the vertical
    s.v = [0.0] * 32
    return s


def test_the_cpp_process_answers_states_with_heading_holding_commands(
        lcm_url: str, procs: list, tmp_path: Path) -> None:
    exe = build(tmp_path)
    proc = subprocess.Popen([str(exe), lcm_url, "0.25", "20"], stdout=subprocess.PIPE,
                            text=True, start_new_session=True)
    procs.append(proc)
    assert proc.stdout is not None and proc.stdout.readline().startswith("heading_hold: on")
    bus = Bus(lcm_url, source="test")
    commands = bus.subscribe("COMMAND", command_t, policy="each")
    time.sleep(0.2)  # its subscription joined
    for k in range(100):  # 1 s of robot time at 100 Hz, heading 0.3 rad
        bus.publish("NETWORK_CASSIE_STATE", state(10_000 * k, 0.3))
        bus.drain(0.002)
    bus.drain(0.3)
    got = []
    while (c := commands.pop()) is not None:
        got.append(c)
    assert 8 <= len(got) <= 11, len(got)  # 10 Hz of robot time, not one per state
    assert [c.header.utime for c in got][:3] == [0, 100_000, 200_000]
    for c in got:
        assert c.header.source == "heading_hold" and c.mode == 0
        assert c.vx == pytest.approx(0.25)
        assert c.yaw_rate == pytest.approx(-0.3)  # turns back to heading 0
    assert [c.header.seq for c in got] == list(range(len(got)))
