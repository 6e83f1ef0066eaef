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
    # one histogram panel per loop and per hop, with the deadlines and budgets drawn
    assert (tmp_path / "plots" / "loops_exec_hist.png").stat().st_size > 10_000
    assert (tmp_path / "plots" / "hops_latency_hist.png").stat().st_size > 5_000


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


def test_the_udp_link_table_counts_what_one_end_sent_and_the_other_never_got():
    """Each direction: datagrams sent by one end against received by the other, over the span
    both reported, interpolated at its ends (the two processes report at different times),
    beside the receiver's own count of sequence gaps (blind to a lockstep resend)."""
    from lcmtypes import loop_timing_t
    from tools.report import _link

    def series(counters: dict[str, float], rate: float, t0_s: float, n: int, dt_s: float):
        msgs, ts = [], []
        for k in range(n):
            m = loop_timing_t()
            m.counter_names = list(counters)
            m.counter_values = [v * rate * k * dt_s for v in counters.values()]
            m.num_counters = len(counters)
            msgs.append(m)
            ts.append(round((t0_s + k * dt_s) * 1e6))
        return msgs, ts

    # the sim sends 2000 datagrams/s from t = 0; the estimator, up from t = 3 s, gets 95 %
    sim = series({"packets_sent": 1.0, "commands_received": 0.9, "commands_lost": 0.1},
                 2000.0, 0.0, 200, 0.1)
    est = series({"packets_received": 0.95, "packets_lost": 0.0}, 2000.0, 3.03, 150, 0.1)
    bridge = series({"packets_sent": 1.0}, 2000.0, 2.97, 150, 0.1)
    link = _link({"sim": sim, "state_estimator": est, "torque_bridge": bridge})
    down = link["target PC -> estimator"]
    assert abs(down["sent"] - 2000.0 * down["span_s"]) < 1.0
    assert abs(down["lost_ratio"] - 0.05) < 1e-3 and down["seq_gaps"] == 0.0
    up = link["torque bridge -> target PC"]
    assert abs(up["lost_ratio"] - 0.1) < 1e-3 and abs(up["seq_gaps"] - 0.1 * up["sent"]) < 1.0
