"""Every loop measures itself: period, execution time, CPU time, lateness, misses, input age.

Per tick the loop records a few integers into preallocated arrays (no allocation); about ten
times a second the window is summarised into one ``loop_timing_t`` (with the raw samples, so a
report from a log gets exact percentiles) and the window restarts. CPU time is measured twice:
per tick, the loop thread's own (``CLOCK_THREAD_CPUTIME_ID``: the work, which preemption does
not inflate), and per window, the whole process's (every thread, LCM's receive thread
included), which is what the process takes of the machine.
"""

from __future__ import annotations

import bisect
import time
from collections.abc import Mapping

import numpy as np

from lcmtypes import loop_timing_t

#: a trigger stamped further than this before its arrival (or after it) is timed from its
#: arrival: its stamp is not a send time of this host's CLOCK_MONOTONIC (a replayed log, whose
#: messages keep their recorded stamps: perception reported a lateness of 161,608 ms; or
#: another host's clock). ``cassie report`` leaves hop pairs this far apart out, too.
FOREIGN_CLOCK_NS = 1_000_000_000

_NS_PER_MS = 1e6


def _quantile(ordered: list[float], q: float) -> float:
    """The ``q`` quantile of sorted ``ordered``, interpolated as ``np.percentile`` does
    (its default "linear" method: position ``q * (n - 1)``)."""
    h = q * (len(ordered) - 1)
    lo = int(h)
    if lo + 1 >= len(ordered):
        return ordered[-1]
    return ordered[lo] + (h - lo) * (ordered[lo + 1] - ordered[lo])


def _p50_p99_max(ordered: list[float]) -> tuple[float, float, float]:
    return _quantile(ordered, 0.5), _quantile(ordered, 0.99), ordered[-1]


class LoopTimer:
    """Collects one loop's per-tick timing and summarises it into timing messages."""

    def __init__(
        self,
        process: str,
        loop: str,
        kind: str,
        deadline_s: float | None,
        target_rate_hz: float | None,
        report_period_s: float = 0.1,
        capacity: int = 8192,
    ) -> None:
        self.process = process
        self.loop = loop
        self.kind = kind
        self.deadline_ms = (deadline_s or 0.0) * 1e3
        self.target_rate_hz = target_rate_hz or 0.0
        self.report_period_ns = int(report_period_s * 1e9)
        #: the window's samples, ms, one row each: exec, lateness, cpu, input age (-1: none);
        #: one array, so a report sorts and converts them in one call each
        self._samples = np.zeros((4, capacity), dtype=np.float32)
        self._capacity = capacity
        self._n = 0
        self._period_sum_ns = 0
        self._period_max_ns = 0
        self._prev_start_ns = 0
        self._window_start_ns = 0
        self._misses = 0
        self.ticks_total = 0
        self.misses_total = 0
        self.overruns_total = 0
        self.stale_skipped_total = 0
        self.decode_errors_total = 0
        self.rate_skipped_total = 0
        self.last_utime = 0
        self._window_cpu_ns = time.process_time_ns()

    def record(
        self,
        start_ns: int,
        end_ns: int,
        lateness_ns: int,
        input_age_ns: int,
        missed: bool,
        cpu_ns: int = 0,
    ) -> None:
        """Record one tick. ``input_age_ns`` < 0 means the loop had no timestamped input;
        ``cpu_ns`` is the loop thread's CPU time spent in the tick."""
        if self._window_start_ns == 0:
            self._window_start_ns = start_ns
        if self._prev_start_ns:
            period = start_ns - self._prev_start_ns
            self._period_sum_ns += period
            if period > self._period_max_ns:
                self._period_max_ns = period
        self._prev_start_ns = start_ns
        i = self._n
        if i < self._capacity:
            sm = self._samples
            sm[0, i] = (end_ns - start_ns) / _NS_PER_MS
            sm[1, i] = lateness_ns / _NS_PER_MS
            sm[2, i] = cpu_ns / _NS_PER_MS
            sm[3, i] = input_age_ns / _NS_PER_MS if input_age_ns >= 0 else -1.0
            self._n = i + 1
        self.ticks_total += 1
        if missed:
            self._misses += 1
            self.misses_total += 1

    def start(self, now_ns: int) -> None:
        """Open the first window (the loop is set up): idle windows are reported too, as a
        heartbeat, so a loop waiting for its first input is seen alive."""
        if self._window_start_ns == 0:
            self._window_start_ns = now_ns

    def due(self, now_ns: int) -> bool:
        """True when the current window is long enough to report."""
        return (
            self._window_start_ns != 0 and now_ns - self._window_start_ns >= self.report_period_ns
        )

    def report(
        self,
        now_ns: int,
        status: str = "",
        health: int = 0,
        counters: Mapping[str, float] | None = None,
    ) -> loop_timing_t:
        """Summarise the window into a message and start a new window. ``status``, ``health``
        and ``counters`` are the node's own (``Node.status``, ``health``, ``counters``)."""
        n = self._n
        msg = loop_timing_t()
        msg.header.utime = int(self.last_utime)
        msg.process = self.process
        msg.loop = self.loop
        msg.kind = self.kind
        span_ns = max(now_ns - self._window_start_ns, 1)
        msg.window_s = span_ns / 1e9
        msg.rate_hz = n / msg.window_s
        msg.target_rate_hz = float(self.target_rate_hz)
        msg.deadline_ms = float(self.deadline_ms)
        msg.ticks = n
        msg.ticks_total = self.ticks_total
        msg.deadline_misses = self._misses
        msg.deadline_misses_total = self.misses_total
        msg.overruns_total = self.overruns_total
        msg.stale_skipped_total = self.stale_skipped_total
        msg.decode_errors_total = self.decode_errors_total
        msg.rate_skipped_total = self.rate_skipped_total
        cpu_now = time.process_time_ns()
        msg.process_cpu_s = cpu_now / 1e9  # CPU time of the process since it started
        msg.process_cpu_share = (cpu_now - self._window_cpu_ns) / span_ns
        self._window_cpu_ns = cpu_now
        msg.status = status
        msg.health = int(health)
        if counters:
            msg.counter_names = list(counters)
            msg.counter_values = [float(v) for v in counters.values()]
            msg.num_counters = len(msg.counter_names)
        periods = max(n - 1, 1)
        msg.period_mean_ms = self._period_sum_ns / periods / _NS_PER_MS if n > 1 else 0.0
        msg.period_max_ms = self._period_max_ns / _NS_PER_MS
        if n:
            window = self._samples[:, :n]
            # one sort of the window, percentiles read off it: the report runs right after a
            # tick at the loop's priority, and np.percentile, np.stack and np.nan_to_num
            # (~0.25 ms together with cold caches) held up the loops below it on the CPU
            ex, la, cp, ag = np.sort(window, axis=1).tolist()
            msg.exec_p50_ms, msg.exec_p99_ms, msg.exec_max_ms = _p50_p99_max(ex)
            msg.lateness_p50_ms, msg.lateness_p99_ms, msg.lateness_max_ms = _p50_p99_max(la)
            msg.cpu_p50_ms, msg.cpu_p99_ms, msg.cpu_max_ms = _p50_p99_max(cp)
            first_age = bisect.bisect_left(ag, 0.0)  # (sorted: the -1 of "no input" first)
            if first_age < n:
                (msg.input_age_p50_ms, msg.input_age_p99_ms,
                 msg.input_age_max_ms) = _p50_p99_max(ag[first_age:])
            else:
                msg.input_age_p50_ms = msg.input_age_p99_ms = msg.input_age_max_ms = -1.0
            msg.num_samples = n
            msg.exec_ms, msg.lateness_ms, msg.cpu_ms, msg.input_age_ms = window.tolist()
        # next window
        self._n = 0
        self._misses = 0
        self._period_sum_ns = 0
        self._period_max_ns = 0
        self._window_start_ns = now_ns
        self._prev_start_ns = 0
        return msg
