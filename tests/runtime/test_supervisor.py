"""The supervisor with real processes: restart after SIGKILL, crash loops, clean shutdown."""

from __future__ import annotations

import copy
import os
import signal
import time
from pathlib import Path

import psutil

from lcmtypes import supervisor_status_t
from runtime.bus import Bus
from runtime.pairing import sign_message
from tests.conftest import PROFILES, cassie, wait_for


def _alive(pid: int) -> bool:
    try:
        return psutil.Process(pid).status() != psutil.STATUS_ZOMBIE
    except psutil.NoSuchProcess:
        return False


def test_supervisor_restarts_killed_child_marks_crash_loop_and_leaves_no_orphans(
    lcm_url, procs, tmp_path: Path
):
    grandchild_file = tmp_path / "grandchild.pid"
    profile = tmp_path / "profile.yaml"
    profile.write_text(
        f"include: [{PROFILES / 'supervised.yaml'}]\n"
        "profile: supervised_test\n"
        "launch: [ticker, echo, crasher]\n"
        f"overrides: {{ticker: {{params: {{grandchild_pid_file: '{grandchild_file}'}}}}}}\n"
    )
    bus = Bus(lcm_url, source="test")
    status = bus.subscribe("SUPERVISOR_STATUS", supervisor_status_t)
    sup = cassie("launch", str(profile), "--no-live", "--log-dir", str(tmp_path / "logs"))
    procs.append(sup)

    def by_name() -> dict[str, object]:
        msg = status.peek()
        return {p.name: p for p in msg.processes} if msg is not None else {}

    def poll() -> None:
        bus.drain(0.1)
        status.latest()

    wait_for(
        lambda: (
            by_name().get("echo") is not None
            and by_name()["echo"].state == "ready"
            and by_name()["ticker"].state == "ready"
        ),
        30,
        poll=poll,
        what="ticker and echo ready",
    )
    first_pid = by_name()["ticker"].pid
    seen_pids = {p.pid for p in by_name().values() if p.pid}
    assert grandchild_file.exists()
    grandchild = int(grandchild_file.read_text())
    assert _alive(first_pid) and _alive(grandchild)

    # 1. SIGKILL a child: the supervisor restarts it (new pid, restarts == 1, ready again).
    os.kill(first_pid, signal.SIGKILL)
    wait_for(
        lambda: (
            by_name()["ticker"].restarts == 1
            and by_name()["ticker"].state == "ready"
            and by_name()["ticker"].pid != first_pid
        ),
        20,
        poll=poll,
        what="ticker restarted",
    )
    seen_pids |= {p.pid for p in by_name().values() if p.pid}

    # 2. A child that fails every time ends in crash_loop after max_restarts (2) restarts.
    wait_for(
        lambda: by_name()["crasher"].state == "crash_loop",
        30,
        poll=poll,
        what="crasher in crash_loop",
    )
    crasher = by_name()["crasher"]
    assert crasher.restarts == 2
    assert crasher.exit_code == 3
    assert "giving up" in crasher.detail
    # the healthy ones are untouched
    assert by_name()["echo"].state == "ready" and by_name()["echo"].restarts == 0
    grandchild2 = int(grandchild_file.read_text())
    seen_pids |= {p.pid for p in by_name().values() if p.pid}
    seen_pids |= {grandchild, grandchild2}

    # 3. SIGINT: everything shuts down in reverse order and no process is left behind.
    os.kill(sup.pid, signal.SIGINT)
    out, _ = sup.communicate(timeout=30)
    # crasher is not required; but the required ticker was killed mid-run: restarted, it
    # kept the run going, and the run's result says it crashed
    assert sup.returncode == 1, out
    assert "crashed: ticker: 1 time(s), restarted 1 time(s)" in out
    assert "crasher" not in out.split("result:")[1]
    assert "summary of profile supervised_test" in out
    time.sleep(0.2)
    leftovers = [pid for pid in seen_pids if _alive(pid)]
    assert leftovers == [], f"orphans left behind: {leftovers}"
    # ...and the last status message says so.
    bus.drain(0.5)
    final = status.latest()
    assert final.state in ("stopping", "stopped")


def test_duration_run_exits_nonzero_when_a_required_process_fails(lcm_url, procs, tmp_path):
    profile = tmp_path / "profile.yaml"
    profile.write_text(
        f"include: [{PROFILES / 'runtime.yaml'}]\n"
        "profile: required_failure\n"
        "launch: [ticker, crasher]\n"
        "overrides: {crasher: {required: true, restart: {max_restarts: 1}}}\n"
    )
    sup = cassie(
        "launch", str(profile), "--no-live", "--duration", "20", "--log-dir", str(tmp_path / "logs")
    )
    procs.append(sup)
    out, _ = sup.communicate(timeout=60)
    assert sup.returncode == 1, out
    assert "FAILED (crasher)" in out
    assert "failing on purpose" in (tmp_path / "logs" / "crasher.log").read_text()


def test_duration_run_prints_summary_and_exits_zero(lcm_url, procs, tmp_path):
    sup = cassie(
        "launch",
        str(PROFILES / "runtime.yaml"),
        "--no-live",
        "--duration",
        "3",
        "--log-dir",
        str(tmp_path / "logs"),
    )
    procs.append(sup)
    out, _ = sup.communicate(timeout=60)
    assert sup.returncode == 0, out
    assert "result: ok" in out
    lines = {
        line.split()[0]: line for line in out.splitlines() if line.startswith(("ticker", "echo"))
    }
    # the loop rate column comes from the processes' own TIMING messages
    assert float(lines["ticker"].split()[6]) > 100.0


def test_a_process_reporting_a_fault_fails_the_run_though_it_stays_alive(lcm_url, procs, tmp_path):
    profile = tmp_path / "profile.yaml"
    profile.write_text(
        f"include: [{PROFILES / 'runtime.yaml'}]\nprofile: faulting\nlaunch: [ticker, faulty]\n"
    )
    sup = cassie("launch", str(profile), "--no-live", "--duration", "4",
                 "--log-dir", str(tmp_path / "logs"))
    procs.append(sup)
    out, _ = sup.communicate(timeout=60)
    assert sup.returncode == 1, out
    assert "faulty reports a fault: fell over on purpose" in out
    assert "fault: faulty: fell over on purpose" in out and "FAILED (faulty)" in out


def test_readiness_comes_from_timing_and_the_cpu_column_is_a_real_average(lcm_url, procs,
                                                                          tmp_path):
    bus = Bus(lcm_url, source="test")
    status = bus.subscribe("SUPERVISOR_STATUS", supervisor_status_t, policy="each")
    sup = cassie("launch", str(PROFILES / "runtime.yaml"), "--no-live", "--duration", "6",
                 "--log-dir", str(tmp_path / "logs"))
    procs.append(sup)
    seen: list[supervisor_status_t] = []

    def poll() -> None:
        bus.drain(0.1)
        while (m := status.pop()) is not None:
            seen.append(m)

    wait_for(lambda: sup.poll() is not None, 60, poll=poll, what="the launch to end")
    running = [m for m in seen if m.state == "running"]
    assert len(running) >= 3
    ticker = [next(p for p in m.processes if p.name == "ticker") for m in running]
    assert all(t.state == "ready" for t in ticker)
    assert all(0 <= t.last_message_age_s < 1.0 for t in ticker)  # its TIMING heartbeat
    # sampled over a second, not a 1 ms glimpse: a 200 Hz Python loop is never 0.0 % of a core
    assert all(t.cpu_percent > 0.0 for t in ticker[1:]), [t.cpu_percent for t in ticker]
    assert ticker[-1].cpu_s > ticker[0].cpu_s > 0
    me = next(p for p in running[-1].processes if p.name == "supervisor")
    assert 0 <= me.cpu_percent < 10.0 and me.cpu_s > 0  # (psutil counts in 10 ms ticks)


def test_garbage_spoofed_timing_and_unknown_orders_are_ignored_and_counted(lcm_url, tmp_path):
    """TIMING for a process the supervisor does not run, or not sent by it, feeds nothing;
    an order that does not decode, names no process of the stack or asks for nothing it
    knows is not carried out; each is counted and the summary says so."""
    import io

    from lcmtypes import loop_timing_t, supervisor_orders_t
    from runtime.config import load_profile
    from runtime.supervisor import Supervisor

    out = io.StringIO()
    sup = Supervisor(load_profile(PROFILES / "supervised.yaml"), log_dir=tmp_path, out=out,
                     live_table=False)
    try:
        spoof = loop_timing_t()
        spoof.process, spoof.header.source, spoof.status = "ticker", "not-ticker", "fine"
        stranger = loop_timing_t()
        stranger.process = stranger.header.source = "intruder"
        # the right process and source, but not signed with this launch's key
        forged = loop_timing_t()
        forged.process = forged.header.source = "ticker"
        forged.status, forged.health = "fine", 2
        other_launch = sign_message(copy.copy(forged), b"k" * 16)
        for raw in (b"\x00garbage", spoof.encode(), stranger.encode(), forged.encode(),
                    other_launch):
            sup._on_timing("TIMING", raw)
        assert sup.children["ticker"].status != "fine"
        assert not sup.children["ticker"].fault
        assert sup.refused["TIMING"] == 5
        sup._on_timing("TIMING", sign_message(forged, sup.timing_key))
        assert sup.refused["TIMING"] == 5  # the launch's own key: not refused
        bad = supervisor_orders_t()
        bad.process, bad.order = "ticker", "explode"
        nobody = supervisor_orders_t()
        nobody.process, nobody.order = "intruder", "start"
        for raw in (b"\x01junk", bad.encode(), nobody.encode()):
            sup._on_order("SUPERVISOR_ORDERS", raw)
        assert all(c.popen is None for c in sup.children.values())  # nothing was started
        assert sup.refused == {"TIMING": 5, "order": 3}
        sup._print_summary()
        text = out.getvalue()
        assert "ignored: 5 TIMING message(s)" in text and "ignored: 3 order message(s)" in text
        assert "ignored order #1: malformed" in text  # said as it happened
        assert "last: start of unknown process 'intruder'" in text
    finally:
        sup.bus.close()


def test_a_replayed_signed_timing_message_is_refused(lcm_url, tmp_path):
    """The tag proves the launch; the send time, which the tag covers, proves freshness: a
    TIMING message recorded and sent again is not taken (it could say a dead copy is well)."""
    import io
    import subprocess

    from lcmtypes import loop_timing_t
    from runtime.config import load_profile
    from runtime.supervisor import Supervisor

    sup = Supervisor(load_profile(PROFILES / "supervised.yaml"), log_dir=tmp_path,
                     out=io.StringIO(), live_table=False)
    child = sup.children["ticker"]
    child.popen = subprocess.Popen(["sleep", "30"])  # (a live copy for TIMING to be about)
    try:
        msg = loop_timing_t()
        msg.process = msg.header.source = "ticker"
        msg.status, msg.header.send_mono_ns = "first", 1_000
        first = sign_message(copy.copy(msg), sup.timing_key)
        sup._on_timing("TIMING", first)
        assert child.status == "first" and not sup.refused
        msg.status, msg.header.send_mono_ns = "second", 2_000
        sup._on_timing("TIMING", sign_message(msg, sup.timing_key))
        sup._on_timing("TIMING", first)  # the recording of the first, sent again
        assert child.status == "second"
        assert sup.refused == {"TIMING": 1}
        assert "replayed" in sup.refused_last["TIMING"]
    finally:
        child.popen.kill()
        child.popen.wait()
        child.popen = None
        sup.bus.close()
