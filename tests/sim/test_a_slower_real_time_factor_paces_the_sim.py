"""`mode: realtime` with `rtf: 0.5`: the sim paces sim time at half the wall clock (each 0.5 ms
step on a 1 ms wall-clock slot), and says so in its counters; a lockstep profile refuses an
rtf, with a message naming the key."""

from __future__ import annotations

from pathlib import Path

import pytest

from lcmtypes import loop_timing_t
from runtime.config import HW_CONFIG_DIR, load_profile
from runtime.errors import ConfigError
from tests.conftest import cassie, profile_bus, wait_for


def _profile(tmp_path: Path, body: str) -> Path:
    p = tmp_path / "rtf.yaml"
    p.write_text(f"include: [{HW_CONFIG_DIR / 'sim.yaml'}]\nprofile: rtf_test\n"
                 "launch: [sim]\n" + body)
    return p


@pytest.mark.timing  # wall-clock rates of a live loop: for a quiet machine, not the default run
def test_the_sim_runs_at_half_speed_with_rtf_one_half(lcm_url, procs, tmp_path):
    prof = _profile(tmp_path, "rtf: 0.5\n")
    bus = profile_bus(prof)
    timing = bus.subscribe("TIMING", loop_timing_t, policy="each")
    procs.append(cassie("run", "sim", "--profile", str(prof), "--duration", "8"))
    seen: list[tuple[float, float, int]] = []  # (window wall s, sim time, ticks)

    def poll() -> None:
        bus.drain(0.1)
        while (m := timing.pop()) is not None:
            if m.process == "sim" and m.ticks and "sim_time_s" in m.counter_names:
                seen.append((m.window_s, m.counter_values[m.counter_names.index("sim_time_s")],
                             m.ticks))

    wait_for(lambda: len(seen) >= 25, 40, poll=poll, what="2.5 s of the sim's TIMING")
    steady = seen[5:]
    wall = sum(w for w, _, _ in steady[1:])
    sim = steady[-1][1] - steady[0][1]
    assert 0.45 < sim / wall < 0.52  # half speed (catch-up never runs ahead of the clock)
    rate = sum(n for _, _, n in steady[1:]) / wall
    assert 900 < rate < 1010  # one 0.5 ms step per 1 ms of wall time


def test_a_lockstep_profile_refuses_a_real_time_factor(tmp_path):
    with pytest.raises(ConfigError, match=r"rtf.*needs mode: realtime"):
        load_profile(_profile(tmp_path, "mode: lockstep\nrtf: 0.5\n"))
