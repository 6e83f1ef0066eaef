"""The dashboard as a real process on a real LCM bus: headless recording, bounded buffers."""

from __future__ import annotations

import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from runtime.bus import Bus
from runtime.config import HW_CONFIG_DIR
from tests.conftest import cassie, profile_bus, wait_for
from tests.dashboard import fake_stack
from tests.dashboard.rrd import read_rrd, view_origins
from tools.dashboard.collector import Collector

HOPS = ("state_to_torque", "sensor_to_applied", "state_to_plan", "depth_to_map",
        "map_to_footholds", "depth_to_footholds")


def _wait_for_line(proc: subprocess.Popen[str], text: str, timeout: float) -> list[str]:
    """Lines of the child's output up to the first one containing ``text``."""
    lines: list[str] = []
    done = threading.Event()

    def read() -> None:
        assert proc.stdout is not None
        for line in proc.stdout:
            lines.append(line)
            if text in line:
                done.set()
                return

    threading.Thread(target=read, daemon=True).start()
    if not done.wait(timeout):
        raise AssertionError(f"no {text!r} within {timeout} s; output so far: {''.join(lines)}")
    return lines


def test_headless_recording_of_a_short_run_has_every_view(
    lcm_url: str, procs: list[subprocess.Popen[str]], tmp_path: Path
) -> None:
    out = tmp_path / "logs" / "run.rrd"  # a folder the dashboard must create
    # a profile of our own (hw_config's channel names), so that this test does not depend on
    # the processes of hw_config/sim.yaml
    profile = tmp_path / "dash.yaml"
    profile.write_text(
        f"profile: dash\ninclude: [{HW_CONFIG_DIR / 'hosts.yaml'}, "
        f"{HW_CONFIG_DIR / 'channels.yaml'}]\n"
        "processes:\n"
        # (named as one of the fake stack's processes: its per-loop panel gets their TIMING)
        "  osc: {host: nuc, module: tests.procs.ticker, rate_hz: 10, deadline_ms: 1,\n"
        "        outputs: {out: command}}\n"
        "launch: [osc]\n"
    )
    proc = cassie("dashboard", "--save", str(out), "--duration", "60", "--profile", str(profile))
    procs.append(proc)
    _wait_for_line(proc, "dashboard: listening", 30)
    # each channel on its LCM domain (a host's bus, or the network), as the stack publishes it
    published = fake_stack.publish_for(profile_bus(profile, source="fake"), 3.0)
    proc.send_signal(signal.SIGTERM)  # as the launcher stops it: the file must be complete
    rest, _ = proc.communicate(timeout=30)
    assert proc.returncode == 0, rest
    summary = [x for x in rest.splitlines() if "messages received" in x]
    assert summary, rest
    received = int(summary[0].split(" messages received")[0].rsplit(" ", 1)[1])
    assert received > 0.5 * published  # UDP on a loaded 2-core box may lose some

    rec = read_rrd(out)
    assert rec.blueprints == 1
    views = view_origins(out)
    assert set(views) == {
        "Robot, terrain, footholds and plan", "Elevation map", "S3 mask", "Loop rate (Hz)",
        "Execution time (ms)", "Lateness (ms)", "Deadline misses per window",
        "Hop latency (ms)", "MPFC solve (ms)", "OSC tick (ms)", "Dashboard load",
        "Supervisor and gait states", "osc execution (ms)",  # one panel per loop as well
    }
    for name, origin in views.items():  # every view of the layout has data under its origin
        if origin != "/":
            assert any(e == f"/{origin}" or e.startswith(f"/{origin}/") for e in rec.rows), name
    for ent, timelines in rec.timelines.items():  # static entities have none
        assert timelines in (set(), {"sim_time", "wall_time"}), ent
    expected = [
        *(f"/timing/{m}/{p}/{loop}" for p, loop in fake_stack.LOOPS
          for m in ("rate_hz", "exec_ms", "lateness_ms", "deadline_misses")),
        *(f"/latency/{h}_ms" for h in HOPS),
        "/mpfc/solve_ms", "/mpfc/optimizer_ms", "/mpfc/gait", "/osc/tick_ms",
        "/supervisor/states/_stack", *(f"/supervisor/states/{p}" for p in fake_stack.PROCESSES),
        "/world/robot/pelvis", "/world/robot/legs", "/world/robot/feet", "/world/camera",
        "/world/elevation_map", "/world/footholds", "/world/plan/footsteps",
        "/maps/elevation", "/maps/s3_mask", "/dashboard/dropped_total",
    ]
    missing = [e for e in expected if e not in rec.rows]
    assert not missing, missing
    for hop in HOPS:
        lat = rec.scalars(f"/latency/{hop}_ms")
        assert lat and all(0 < x < 1000 for x in lat), hop
    legs = rec.column("/world/robot/legs", "LineStrips3D:strips")
    assert len(legs[-1]) == 2 and len(legs[-1][0]) == 8  # pelvis + 7 bodies per leg
    assert rec.rows["/world/robot/pelvis"] <= 35 * 4  # 30 Hz of sim time, not 1 kHz
    s3 = [x[0] for x in rec.column("/supervisor/states/s3", "StateChange:state")]
    assert s3[-1] == "backoff"

    # the CLI reads it too, as a user would check it
    rerun_cli = Path(sys.executable).with_name("rerun")
    stats = subprocess.run([str(rerun_cli), "rrd", "stats", str(out)], capture_output=True,
                           text=True, timeout=60)
    assert stats.returncode == 0, stats.stderr
    assert "sim_time" in stats.stdout and "wall_time" in stats.stdout


def test_flood_beyond_the_buffer_is_dropped_and_counted(lcm_url: str) -> None:
    cap = 50
    col = Collector(lcm_url, {"FLOOD": cap, "BIG": 10}, keep_bytes={"BIG": 8})
    col.start()
    try:
        bus = Bus(lcm_url, source="flood")
        n = 5000
        bus.publish("BIG", bytes(range(100)) * 100)
        for i in range(n):  # far faster than anyone takes them
            bus.publish("FLOOD", i.to_bytes(4, "big") + bytes(1000))
        last = -1

        def settled() -> bool:
            nonlocal last
            got = col.stats["FLOOD"].received
            done = got == last
            last = got
            return done and got > 0

        wait_for(settled, 10, poll=lambda: time.sleep(0.2), what="the flood to arrive")
        st = col.stats["FLOOD"]
        assert st.received > cap * 10  # most of the flood arrived ...
        assert col.pending()["FLOOD"] == cap  # ... but only `cap` are kept ...
        assert st.dropped == st.received - cap  # ... and every other one was counted
        taken = col.take()
        assert taken["BIG"] == [bytes(range(8))]  # cut to its first bytes on arrival
        kept = taken["FLOOD"]
        ids = [int.from_bytes(m[:4], "big") for m in kept]
        assert ids == sorted(ids) and len(ids) == cap  # the newest, in order
        assert ids[-1] >= n - 1 - (n - st.received)  # the newest that arrived is kept
        assert col.pending()["FLOOD"] == 0
        assert col.totals() == (st.received + 1, st.dropped)
    finally:
        col.stop()


def test_bad_arguments_fail_clearly() -> None:
    from tools.dashboard import main

    with pytest.raises(SystemExit):
        main(["--no-such-flag"])
    assert main(["--rate", "0", "--save", "x.rrd"]) == 2
