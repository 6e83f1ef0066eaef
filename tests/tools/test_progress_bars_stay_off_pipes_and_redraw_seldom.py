"""The benchmarks' and tools' progress bars: off when stderr is not a terminal (a pipe, a log,
a test's capture) or when asked to be quiet; on a terminal, an ETA redrawn at most about twice
a second however often the loop updates it, and no monitor thread."""

from __future__ import annotations

import io
import sys
import threading

import pytest

from tools.benchmarks.common import progress


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_a_bar_is_off_on_a_pipe_and_when_quiet(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(sys, "stderr", io.StringIO())
    with progress(10, "off") as bar:
        bar.update(10)
    assert bar.disable and sys.stderr.getvalue() == ""
    monkeypatch.setattr(sys, "stderr", _Terminal())
    with progress(10, "quiet", quiet=True) as bar:
        bar.update(10)
    assert bar.disable and sys.stderr.getvalue() == ""


def test_on_a_terminal_a_fast_loop_redraws_its_bar_only_a_few_times(
        monkeypatch: pytest.MonkeyPatch) -> None:
    term = _Terminal()
    monkeypatch.setattr(sys, "stderr", term)
    threads = threading.active_count()
    with progress(100_000, "fast", unit="tick") as bar:
        assert threading.active_count() == threads  # no tqdm monitor thread
        for _ in range(100_000):
            bar.update(1)
    draws = term.getvalue().count("\r")
    assert "fast" in term.getvalue() and "tick" in term.getvalue()
    assert draws <= 10, draws  # the first, the close, and one per 0.5 s at most in between
