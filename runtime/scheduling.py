"""A process's own CPU scheduling: real-time priority, nice value, CPU affinity.

A process applies its nice value and CPU affinity to itself when it starts (``cassie run``),
and its real-time priority once its node is set up, just before its loop starts: compiling
numba kernels or loading a model at SCHED_FIFO would starve everything else on that core for
seconds. Threads the loop starts (a receive thread) inherit it. The priority is asked for
with ``SCHED_RESET_ON_FORK``: a child it spawns runs at normal priority and can never hold up
the loop. Each setting is best-effort: one that cannot be applied (no permission) is
reported, and the process runs on without it.
"""

from __future__ import annotations

import os
import time
from typing import Any


def apply_scheduling(proc: Any, realtime: bool = False) -> list[str]:
    """Apply ``proc``'s ``nice`` and ``cpu_affinity`` (a ``ProcessConfig``) to this process,
    or with ``realtime`` its ``rt_priority``; returns one line per setting saying what
    happened."""
    if realtime:
        return rt_priority(getattr(proc, "rt_priority", None))
    notes = []
    aff = getattr(proc, "cpu_affinity", None)
    if aff:
        try:
            os.sched_setaffinity(0, aff)
            notes.append(f"cpu affinity {list(aff)}: applied")
        except OSError as exc:
            notes.append(f"cpu affinity {list(aff)}: failed ({exc.strerror})")
    nice = getattr(proc, "nice", None)
    if nice is not None:
        try:
            os.setpriority(os.PRIO_PROCESS, 0, nice)
            notes.append(f"nice {nice}: applied")
        except OSError as exc:
            notes.append(f"nice {nice}: failed ({exc.strerror})")
    return notes


def lock_memory() -> str:
    """Lock all of this process's memory, now and to come, into RAM (``mlockall``): a loop
    must never wait for a page to come back. Measured on this VM, whose kernel pages idle
    memory out on its own (DAMON ``pageout``): the first ticks of the OSC and the bridge after
    a long start-up cost ~220 ms of CPU each in page faults, and Cassie fell as the holder let
    go. Best-effort; returns what happened."""
    import ctypes

    try:
        libc = ctypes.CDLL("libc.so.6", use_errno=True)
        if libc.mlockall(3) == 0:  # MCL_CURRENT | MCL_FUTURE
            return "memory locked (mlockall)"
        return f"memory lock failed ({os.strerror(ctypes.get_errno())})"
    except OSError as exc:
        return f"memory lock failed ({exc})"


def pin_to_supervisor_host(profile: Any, host: str | None = None) -> tuple[int, ...] | None:
    """Pin this process (best-effort) to the CPUs of the host the supervisor and the tools
    stand on (``profile.supervisor_host``: the laptop; a deputy: ``host``), never to the
    NUC's; returns those CPUs (None when that host names none), for the helpers too."""
    home = profile.hosts.get(host or profile.supervisor_host)
    cpus = home.cpus if home is not None else None
    if cpus:
        try:
            os.sched_setaffinity(0, cpus)
        except OSError:
            pass
    return cpus


def rt_priority(prio: int | None, pid: int = 0) -> list[str]:
    """SCHED_FIFO at ``prio`` for the calling thread (and the threads it starts), or for the
    main thread of ``pid``; one line saying what happened."""
    notes = []
    if prio is not None:
        try:
            os.sched_setscheduler(
                pid, os.SCHED_FIFO | os.SCHED_RESET_ON_FORK, os.sched_param(int(prio))
            )
            notes.append(f"SCHED_FIFO priority {prio}: applied")
        except (OSError, AttributeError) as exc:
            why = getattr(exc, "strerror", None) or str(exc)
            notes.append(
                f"SCHED_FIFO priority {prio}: failed ({why}); running at normal priority "
                "(real-time priority needs root or CAP_SYS_NICE, or an rtprio limit: "
                "`ulimit -r`)"
            )
    return notes


def normal_priority() -> None:
    """Back to the normal scheduler (from ``rt_priority``), best-effort."""
    try:
        os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
    except (OSError, AttributeError):
        pass


def describe(pid: int) -> str:
    """What scheduling ``pid`` runs with, e.g. ``fifo 80`` or ``nice 5`` (for status tables)."""
    try:
        policy = os.sched_getscheduler(pid) & ~getattr(os, "SCHED_RESET_ON_FORK", 0)
        if policy == os.SCHED_FIFO:
            return f"fifo {os.sched_getparam(pid).sched_priority}"
        if policy == getattr(os, "SCHED_RR", -1):
            return f"rr {os.sched_getparam(pid).sched_priority}"
        nice = os.getpriority(os.PRIO_PROCESS, pid)
        return f"nice {nice}" if nice else "normal"
    except OSError:
        return "?"


def process_cpu_s(pid: int) -> float:
    """CPU seconds ``pid``'s whole thread group has run, to the nanosecond (the kernel's
    per-process CPU clock, ``CPUCLOCK_SCHED``), ended threads included.

    psutil's figures come in 10 ms clock ticks: over a one-second sample a loop that uses 1 %
    of a core reads 0 % or 2 %. This clock has no such steps. Raises ``OSError`` once the
    process is gone."""
    return time.clock_gettime((~pid << 3) | 2)  # MAKE_PROCESS_CPUCLOCK(pid, CPUCLOCK_SCHED)
