"""``cassie list``, ``cassie order`` and ``cassie logs`` against a real launch: the profiles
and their processes listed, one process restarted from another terminal (a new pid, the
restart counted, ready again), stopped and started, and its log printed."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from lcmtypes import supervisor_status_t
from runtime.bus import Bus
from tests.conftest import PROFILES, REPO, cassie, wait_for


def run(*args: str, timeout: float = 60) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "tools.cli", *args], capture_output=True,
                          text=True, cwd=REPO, timeout=timeout)


def test_list_names_the_profiles_and_a_profiles_processes() -> None:
    out = run("list").stdout
    assert any(line.split()[:2] == ["sim", "realtime"] for line in out.splitlines()), out
    out = run("list", "sim_perception").stdout
    for name in ("sim", "state_estimator", "torque_bridge", "osc", "mpfc", "perception", "s3"):
        assert f"  {name} " in out, out


def test_a_process_of_a_running_launch_is_restarted_stopped_and_started_by_order(
        lcm_url: str, procs: list, tmp_path: Path) -> None:
    profile = str(PROFILES / "supervised.yaml")
    sup = cassie("launch", profile, "--no-live", "--log-dir", str(tmp_path / "logs"))
    procs.append(sup)
    bus = Bus(lcm_url, source="test")
    status = bus.subscribe("SUPERVISOR_STATUS", supervisor_status_t)

    def ticker():  # type: ignore[no-untyped-def]
        msg = status.peek()
        return next((p for p in msg.processes if p.name == "ticker"), None) if msg else None

    wait_for(lambda: (t := ticker()) is not None and t.state == "ready", 60,
             poll=lambda: (bus.drain(0.1), status.latest()), what="ticker ready")
    first = ticker().pid
    done = run("order", "restart", "ticker", "--profile", profile)
    assert done.returncode == 0, done.stdout + done.stderr
    assert f"pid {first} -> " in done.stdout and "restarts 1" in done.stdout, done.stdout
    done = run("order", "stop", "ticker", "--profile", profile)
    assert done.returncode == 0 and "stopped" in done.stdout, done.stdout + done.stderr
    done = run("order", "start", "ticker", "--profile", profile)
    assert done.returncode == 0 and "ready" in done.stdout, done.stdout + done.stderr
    done = run("order", "restart", "nobody", "--profile", profile)
    assert done.returncode == 2 and "not a process of this launch" in done.stderr
    logs = run("logs", "ticker", "--profile", profile)
    assert logs.returncode == 0 and logs.stdout.count("=== start") >= 3, logs.stdout
    assert str(tmp_path / "logs" / "ticker.log") in logs.stderr


def test_screen_puts_each_process_output_on_the_terminal_and_in_its_log(
        lcm_url: str, procs: list, tmp_path: Path) -> None:
    sup = cassie("launch", str(PROFILES / "supervised.yaml"), "--screen", "--duration", "3",
                 "--log-dir", str(tmp_path / "logs"))
    procs.append(sup)
    out, _ = sup.communicate(timeout=120)
    assert "[crasher] crasher: failing on purpose" in out, out[-1500:]
    assert "[ticker] " in out and "ticker: stopped -> starting" in out
    assert "failing on purpose" in (tmp_path / "logs" / "crasher.log").read_text()
