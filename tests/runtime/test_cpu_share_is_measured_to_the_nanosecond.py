"""The supervisor's CPU column comes from the kernel's per-process CPU clocks, so a light
loop never reads 0 % (psutil's 10 ms ticks did) and a gone process costs nothing."""

from __future__ import annotations

import os
import subprocess
import sys
import time

import pytest

from runtime.scheduling import process_cpu_s
from runtime.supervisor_resources import CpuShare

# 200 wakes a second, each spinning 0.1 ms: about 2 % of a core, under two clock ticks a second
LIGHT_LOOP = """
import time
end = time.monotonic() + 5
while time.monotonic() < end:
    t = time.perf_counter()
    while time.perf_counter() - t < 1e-4:
        pass
    time.sleep(0.005)
"""


def test_a_light_loop_reads_a_small_share_never_zero() -> None:
    child = subprocess.Popen([sys.executable, "-c", LIGHT_LOOP])
    try:
        time.sleep(0.3)  # past the interpreter's start-up
        share = CpuShare()
        share.percent([child.pid])
        shares = []
        for _ in range(6):
            time.sleep(0.25)
            shares.append(share.percent([child.pid]))
        assert all(0.3 < s < 30.0 for s in shares), shares
    finally:
        child.kill()
        child.wait()


def test_a_process_gone_counts_nothing_and_a_new_one_counts_from_first_sight() -> None:
    share = CpuShare()
    assert share.percent([os.getpid()]) == 0.0  # first sight: nothing yet
    t = time.perf_counter()
    while time.perf_counter() - t < 0.05:
        pass
    assert share.percent([os.getpid()]) > 10.0
    child = subprocess.Popen([sys.executable, "-c", "pass"])
    child.wait()
    with pytest.raises(OSError):
        process_cpu_s(child.pid)
    assert share.percent([child.pid]) == 0.0
