"""The Python-to-Python LCM hop against its budget (SYSTEM.md: p99 below 0.5 ms)."""

from __future__ import annotations

import pytest

from tools.benchmarks.lcm import run

pytestmark = pytest.mark.timing
BUDGET_P99_MS = 0.5


def test_lcm_hop_at_2khz_is_within_budget(lcm_url, record_figures):
    figures = run([2000.0], seconds=10.0, url=lcm_url)
    record_figures("timing_lcm_hop", figures)
    assert figures["lcm_2000hz_loss_ratio"] < 1e-3
    assert figures["lcm_2000hz_hop_p99_ms"] < BUDGET_P99_MS, (
        f"LCM hop p99 {figures['lcm_2000hz_hop_p99_ms']:.3f} ms over the {BUDGET_P99_MS} ms "
        f"budget (raw UDP on the same run: {figures['udp_2000hz_hop_p99_ms']:.3f} ms)"
    )
