"""Every loop measures itself: period, execution time, CPU time, lateness, misses, input age.

Per tick the loop records a few integers into preallocated arrays (no allocation); about ten
times a second the window is summarised into one ``loop_timing_t`` (with the raw samples, so a
report from a log gets exact percentiles) and the window restarts. CPU time is measured twice:
per tick, the loop thread's own (``CLOCK_THREAD_CPUTIME_ID``: the work, which preemption does
not inflate), and per window, the whole process's (every thread, LCM's receive thread
included), which is what the process takes of the machine.
"""

from __future__ import annotations

import time
from collections.abc import Mapping

import numpy as np

from lcmtypes import loop_timing_t

_NS_PER_MS = 1e6


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
        self._exec = np.zeros(capacity, dtype=np.float32)
        self._late = np.zeros(capacity, dtype=np.float32)
        self._age = np.zeros(capacity, dtype=np.float32)
        self._cpu = np.zeros(capacity, dtype=np.float32)
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
        if i < self._exec.shape[0]:
            self._exec[i] = (end_ns - start_ns) / _NS_PER_MS
            self._late[i] = lateness_ns / _NS_PER_MS
            self._age[i] = input_age_ns / _NS_PER_MS if input_age_ns >= 0 else np.nan
            self._cpu[i] = cpu_ns / _NS_PER_MS
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
            ex, la, ag, cp = self._exec[:n], self._late[:n], self._age[:n], self._cpu[:n]
            # one percentile call for the three always-finite series (each call costs ~30 us)
            three = np.stack((ex, la, cp))
            (e50, l50, c50), (e99, l99, c99) = np.percentile(three, [50, 99], axis=1).tolist()
            emax, lmax, cmax = three.max(axis=1).tolist()
            msg.exec_p50_ms, msg.exec_p99_ms, msg.exec_max_ms = e50, e99, emax
            msg.lateness_p50_ms, msg.lateness_p99_ms, msg.lateness_max_ms = l50, l99, lmax
            msg.cpu_p50_ms, msg.cpu_p99_ms, msg.cpu_max_ms = c50, c99, cmax
            if np.isfinite(ag).any():
                good = ag[np.isfinite(ag)]
                msg.input_age_p50_ms, msg.input_age_p99_ms = (
                    float(x) for x in np.percentile(good, [50, 99])
                )
                msg.input_age_max_ms = float(good.max())
            else:
                msg.input_age_p50_ms = msg.input_age_p99_ms = msg.input_age_max_ms = -1.0
            msg.num_samples = n
            msg.exec_ms = ex.tolist()
            msg.cpu_ms = cp.tolist()
            msg.lateness_ms = la.tolist()
            msg.input_age_ms = np.nan_to_num(ag, nan=-1.0).tolist()
        # next window
        self._n = 0
        self._misses = 0
        self._period_sum_ns = 0
        self._period_max_ns = 0
        self._window_start_ns = now_ns
        self._prev_start_ns = 0
        return msg
