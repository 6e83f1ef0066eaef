"""What the supervisor's processes cost: CPU share, CPU seconds, memory and scheduling.

The supervisor samples them about once a second, beside process control
(``runtime.supervisor``): the CPU share from the kernel's nanosecond CPU clocks over the
time since the previous sample (a real average, not a 1 ms glimpse), the rest through
psutil, each over the process's whole tree (a depth renderer or a viewer it started).
A remote process is its deputy's to measure.
"""

from __future__ import annotations

import os
import time
from collections.abc import Iterable
from typing import TYPE_CHECKING

import psutil

from runtime.scheduling import describe, process_cpu_s

if TYPE_CHECKING:
    from runtime.supervisor import Child


class CpuShare:
    """A process tree's share of a core since the previous call, from the kernel's
    nanosecond CPU clocks (:func:`process_cpu_s`): each pid counts what it ran in between, a
    pid first seen counts from then on, a pid gone since counts nothing."""

    def __init__(self) -> None:
        self._cpu: dict[int, float] = {}
        self._wall = time.monotonic()

    def percent(self, pids: list[int]) -> float:
        """Percent of one core the ``pids`` used together since the previous call."""
        now, ran, seen = time.monotonic(), 0.0, {}
        for pid in pids:
            try:
                seen[pid] = cpu = process_cpu_s(pid)
            except OSError:
                continue
            ran += cpu - self._cpu.get(pid, cpu)
        elapsed, self._wall, self._cpu = now - self._wall, now, seen
        return 100.0 * ran / elapsed if elapsed > 0 else 0.0


def descendants(ps: psutil.Process) -> list[psutil.Process]:
    """The process's live descendants (a depth renderer, a viewer it started): their cost
    is the process's own."""
    try:
        return ps.children(recursive=True)
    except psutil.Error:
        return []


def sample_child(child: Child) -> None:
    """One local child's CPU share, CPU seconds, memory and scheduling into its record (zero
    share and memory when it is gone or cannot be read)."""
    if child.ps is None:
        child.cpu_percent = child.rss_mb = 0.0
        return
    try:
        with child.ps.oneshot():
            t = child.ps.cpu_times()
            child.rss_mb = child.ps.memory_info().rss / 2**20
        cpu_s = t.user + t.system + t.children_user + t.children_system
        kids = descendants(child.ps)
        for kid in kids:
            try:
                kt = kid.cpu_times()
                cpu_s += kt.user + kt.system
            except psutil.Error:
                pass
        child.cpu_percent = child.cpu_share.percent([child.ps.pid] + [k.pid for k in kids])
        child.cpu_s = cpu_s
        child.priority = describe(child.pid)
        aff = child.ps.cpu_affinity()
        child.affinity = ("all" if len(aff) == (os.cpu_count() or len(aff))
                          else ",".join(map(str, aff)))
    except psutil.Error:
        child.cpu_percent = child.rss_mb = 0.0


class ResourceSampler:
    """The supervisor's own CPU share and its local children's, one sample at a time (the
    figures of the status table and of SUPERVISOR_STATUS)."""

    def __init__(self) -> None:
        self.me = psutil.Process()
        self._share = CpuShare()
        #: the supervisor's own share of a core over the last sample's window
        self.cpu_percent = 0.0
        #: monotonic time of the last sample (0: none yet)
        self.last_sample = 0.0

    def sample(self, children: Iterable[Child], now: float) -> None:
        """Sample the supervisor and each local child (``now``: the sample's monotonic time)."""
        self.last_sample = now
        self.cpu_percent = self._share.percent([os.getpid()])
        for child in children:
            if not child.remote:  # (its deputy measures it)
                sample_child(child)

    def own_usage(self) -> tuple[float, float, str]:
        """The supervisor's (CPU seconds, resident MB, scheduling), so its cost is on record."""
        t = self.me.cpu_times()
        return t.user + t.system, self.me.memory_info().rss / 2**20, describe(os.getpid())
