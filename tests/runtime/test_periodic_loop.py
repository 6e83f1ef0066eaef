"""A periodic loop on absolute deadlines: misses are reported, the schedule is kept."""

from __future__ import annotations

import itertools

from lcmtypes import command_t, loop_timing_t
from runtime.bus import Bus
from tests.conftest import PROFILES, cassie, wait_for

PROFILE = str(PROFILES / "runtime.yaml")
PERIOD_US = 10_000  # sleeper runs at 100 Hz; every 20th tick sleeps 35 ms


def test_periodic_loop_reports_slow_tick_and_keeps_its_schedule(lcm_url, procs):
    bus = Bus(lcm_url, source="test")
    out = bus.subscribe("TEST_SLEEPER", command_t, policy="each")
    timing = bus.subscribe("TIMING", loop_timing_t, policy="each")
    procs.append(cassie("run", "sleeper", "--profile", PROFILE, "--duration", "30"))
    slots: list[int] = []
    reports: list[loop_timing_t] = []

    def poll() -> None:
        bus.drain(0.05)
        while (m := out.pop()) is not None:
            slots.append(m.header.utime)
        while (t := timing.pop()) is not None:
            if t.process == "sleeper":
                reports.append(t)

    wait_for(lambda: len(slots) >= 250, 25, poll=poll, what="250 ticks of the sleeper")
    last = reports[-1]
    # The slow ticks are reported as deadline misses, and the slots they overran as skipped.
    assert last.deadline_misses_total >= 10
    assert last.overruns_total >= 2 * 10
    assert last.deadline_ms == 10.0
    # Every tick starts on the grid t0 + k * period...
    assert all(u % PERIOD_US == 0 for u in slots), "a tick ran off its absolute schedule"
    gaps = [b - a for a, b in itertools.pairwise(slots)]
    # ...and after a slow tick the loop skips the slots it missed rather than catching up.
    assert min(gaps) == PERIOD_US
    assert max(gaps) >= 4 * PERIOD_US
    assert sum(g > PERIOD_US for g in gaps) >= 10
    # The measured execution time of the slow ticks is in the raw samples.
    assert max(max(r.exec_ms) for r in reports if r.num_samples) > 30.0
