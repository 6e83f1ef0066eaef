"""`cassie launch --log` records the bus; `cassie report` turns the log into timing tables."""

from __future__ import annotations

import json

from tests.conftest import PROFILES, cassie


def test_report_of_a_logged_launch_prints_channels_loops_and_hops(lcm_url, procs, tmp_path):
    logs = tmp_path / "logs"
    sup = cassie(
        "launch",
        str(PROFILES / "runtime.yaml"),
        "--duration",
        "4",
        "--no-live",
        "--log",
        "--log-dir",
        str(logs),
    )
    procs.append(sup)
    out, _ = sup.communicate(timeout=60)
    assert sup.returncode == 0, out
    assert (logs / "lcm.log").stat().st_size > 10_000
    rep = cassie(
        "report",
        str(logs / "lcm.log"),
        "--budgets",
        str(PROFILES / "budgets.yaml"),
        "--json",
        str(tmp_path / "report.json"),
        "--plots",
        str(tmp_path / "plots"),
    )
    procs.append(rep)
    text, _ = rep.communicate(timeout=120)
    assert rep.returncode == 0, text
    for heading in ("Channels", "Loops", "Hops", "TEST_TICK", "ticker/ticker", "tick -> echo",
                    "CPU (share of one core"):
        assert heading in text
    fig = json.loads((tmp_path / "report.json").read_text())
    assert fig["name"] == "report" and "machine" in fig
    assert 150 < fig["channel_TEST_TICK_rate_hz"] < 230  # the ticker runs at 200 Hz
    assert fig["hop_tick_echo_matched"] > 300
    assert 0 < fig["hop_tick_echo_latency_p50_ms"] < fig["hop_tick_echo_latency_max_ms"]
    assert fig["loop_ticker_ticker_ticks"] > 300
    # CPU: each process's share of a core, measured by itself (TIMING) or by the supervisor
    assert 0 < fig["cpu_ticker_share"] < 0.5 and 0 < fig["cpu_echo_share"] < 0.5
    assert 0 < fig["loop_ticker_ticker_cpu_p50_ms"] <= fig["loop_ticker_ticker_exec_p50_ms"] * 2
    assert fig["cpu_total_share"] >= fig["cpu_ticker_share"] + fig["cpu_echo_share"]
    assert (tmp_path / "plots" / "loops_exec.png").exists()


def test_report_on_missing_log_says_so(tmp_path):
    p = cassie("report", str(tmp_path / "nope.lcm"))
    out, _ = p.communicate(timeout=60)
    assert p.returncode == 2 and "no such log file" in out


def test_the_cpu_window_opens_after_the_last_process_settles_and_closes_at_the_first_end():
    from tools.report import CPU_SETTLE_S, _common_window, _span

    s = 1_000_000
    spans = [(0, 30 * s), (5 * s, 28 * s), (3 * s, 31 * s)]
    lo, hi = _common_window(spans)
    assert lo == 5 * s + int(CPU_SETTLE_S * s) and hi == 28 * s
    # a process that burnt CPU while starting up is judged on its steady state only
    ts = [k * s for k in range(31)]
    cpu = [0.0] * 6 + [10.0 + 0.3 * k for k in range(25)]  # 10 s of start-up work at t = 6 s
    dcpu, dwall = _span(ts, cpu, (lo, hi))
    assert abs(dcpu / dwall - 0.3) < 1e-9
    assert _span(ts, cpu)[0] / _span(ts, cpu)[1] > 0.5
    assert _common_window([(0, 3 * s), (2 * s, 5 * s)]) is None  # too short to judge
