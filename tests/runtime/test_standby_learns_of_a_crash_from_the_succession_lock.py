"""The succession lock (``runtime.succession``): a standby waiting on it learns that the
running copy died the moment the kernel starts ending it, before the exit shows; an ordered
exit gives the lock back and is not taken for a crash; a second copy cannot take a held lock."""

from __future__ import annotations

import os
import select
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

from runtime.succession import Succession, create_lock

HOLDER = """
import sys, time
import numpy as np
from runtime.succession import Succession
from runtime.scheduling import lock_memory
big = np.ones(int(sys.argv[3]) * 2**17)  # MB of pages, locked below: slow to tear down
lock_memory()
s = Succession(__import__("pathlib").Path(sys.argv[1]))
assert s.hold(2.0)
print("held", flush=True)
if sys.argv[2] == "ordered":
    s.release()
    sys.exit(0)
time.sleep(60)
"""


def start_holder(path: Path, how: str, mb: int = 8) -> subprocess.Popen[str]:
    p = subprocess.Popen([sys.executable, "-c", HOLDER, str(path), how, str(mb)],
                         stdout=subprocess.PIPE, text=True, cwd=Path(__file__).parents[2])
    assert p.stdout is not None and p.stdout.readline().strip() == "held"
    return p


def watch(path: Path) -> tuple[Succession, int]:
    r, w = os.pipe()
    s = Succession(path)
    s.watch(w)
    return s, r


def test_a_killed_holder_wakes_its_standby_with_the_lock_before_its_exit_shows(
        tmp_path: Path) -> None:
    path = tmp_path / "p.alive"
    create_lock(path)
    holder = start_holder(path, "crash", mb=400)
    standby, wake = watch(path)
    exited: list[float] = []
    waiter = threading.Thread(target=lambda: (holder.wait(), exited.append(time.monotonic())))
    waiter.start()
    time.sleep(0.2)
    assert not standby.crashed.is_set()  # held: nothing yet
    t_kill = time.monotonic()
    os.kill(holder.pid, signal.SIGKILL)
    assert select.select([wake], [], [], 5.0)[0], "the standby never woke"
    t_woke = time.monotonic()
    waiter.join(5.0)
    assert standby.crashed.is_set() and not standby.ended.is_set()
    print(f"kill -> standby woken {1e3 * (t_woke - t_kill):.1f} ms, "
          f"kill -> exit seen {1e3 * (exited[0] - t_kill):.1f} ms (400 MB locked)")
    # the standby holds it now: the next standby waits on it, a second copy cannot take it
    second = Succession(path)
    assert not second.hold(0.2)
    standby.release()


def test_an_ordered_exit_gives_the_lock_back_and_is_not_taken_for_a_crash(
        tmp_path: Path) -> None:
    path = tmp_path / "p.alive"
    create_lock(path)
    standby, wake = None, -1
    holder = subprocess.Popen([sys.executable, "-c", HOLDER, str(path), "ordered", "1"],
                              stdout=subprocess.PIPE, text=True, cwd=Path(__file__).parents[2])
    assert holder.stdout is not None and holder.stdout.readline().strip() == "held"
    standby, wake = watch(path)
    assert holder.wait(10) == 0
    assert select.select([wake], [], [], 5.0)[0], "the standby never woke"
    assert standby.ended.is_set() and not standby.crashed.is_set()
    # given back: a fresh copy takes it at once
    fresh = Succession(path)
    assert fresh.hold(1.0)
    fresh.release()
