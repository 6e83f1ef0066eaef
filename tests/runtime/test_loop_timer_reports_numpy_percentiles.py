"""A loop's TIMING window: the percentiles it reports are np.percentile's (linear), read off
one sort of the window; ticks without a timestamped input are left out of the input age,
and a window with none at all reports -1; the raw samples go out as recorded."""

from __future__ import annotations

import numpy as np
import pytest

from runtime.timing import LoopTimer


def _window(n: int, seed: int, no_input_every: int = 0) -> tuple[LoopTimer, np.ndarray]:
    rng = np.random.default_rng(seed)
    t = LoopTimer("p", "loop", "message", 0.001, 1000.0)
    rows = []
    for i in range(n):
        e, la, c = (int(x) for x in rng.integers(0, 900_000, size=3))
        age = -1 if no_input_every and i % no_input_every == 0 else int(rng.integers(0, 2e6))
        t.record(i * 1_000_000, i * 1_000_000 + e, la, age, e > 800_000, c)
        rows.append((e / 1e6, la / 1e6, c / 1e6, age / 1e6 if age >= 0 else -1.0))
    return t, np.array(rows, dtype=np.float32)


@pytest.mark.parametrize("n", [1, 2, 3, 10, 199, 2000])
def test_window_figures_match_numpy(n: int):
    t, rows = _window(n, seed=n, no_input_every=3)
    m = t.report(n * 1_000_000)
    for col, name in enumerate(("exec", "lateness", "cpu")):
        x = rows[:, col]
        assert getattr(m, f"{name}_p50_ms") == pytest.approx(np.percentile(x, 50), rel=1e-6)
        assert getattr(m, f"{name}_p99_ms") == pytest.approx(np.percentile(x, 99), rel=1e-6)
        assert getattr(m, f"{name}_max_ms") == pytest.approx(x.max(), rel=1e-6)
    ages = rows[:, 3][rows[:, 3] >= 0]
    if ages.size:
        assert m.input_age_p50_ms == pytest.approx(np.percentile(ages, 50), rel=1e-6)
        assert m.input_age_p99_ms == pytest.approx(np.percentile(ages, 99), rel=1e-6)
    else:
        assert m.input_age_p50_ms == -1.0
    assert m.num_samples == n and m.ticks == n
    assert np.allclose(m.exec_ms, rows[:, 0]) and np.allclose(m.input_age_ms, rows[:, 3])
    assert m.deadline_misses == int((rows[:, 0] > 0.8).sum())


def test_a_window_without_timestamped_inputs_reports_no_age_and_the_next_starts_empty():
    t, _ = _window(50, seed=7, no_input_every=1)
    m = t.report(50_000_000)
    assert (m.input_age_p50_ms, m.input_age_p99_ms, m.input_age_max_ms) == (-1.0, -1.0, -1.0)
    assert all(a == -1.0 for a in m.input_age_ms)
    m2 = t.report(60_000_000)
    assert m2.ticks == 0 and m2.num_samples == 0 and m2.ticks_total == 50
