"""The live fault suite (issue 14): a walking launch on its own LCM port, in lockstep and then
in real time, is hit, one fault at a time, by a kill -9 of each NUC and laptop process, then
by malformed and poisoned messages on every input channel and foreign packets on both UDP
ports. It must not fall; every killed process must be ready again within a second (its
standby takes over: the supervisor's status), the crashes must be in the summary, no NaN
torque may reach the sim, the garbage must be counted where it landed, and in real time a
dead OSC's torques must give way to the bridge's watchdog within its 10 ms.

Slow (about two minutes per mode): ``pytest -m faults``. The figures go to
``$CASSIE_FAULTS_JSON`` (with the mode in the file name) when it is set
(docs/reports/faults.md records the runs).
"""

from __future__ import annotations

import copy
import json
import math
import os
import random
import re
import signal
import socket
import threading
import time
from pathlib import Path
from typing import Any

import pytest

from lcmtypes import (
    command_t,
    loop_timing_t,
    mpfc_output_t,
    robot_state_t,
    supervisor_status_t,
    torque_command_t,
)
from runtime.bus import Bus
from runtime.cassie_packets import OUTPUT_SIZE, encode_input
from runtime.config import HW_CONFIG_DIR, load_profile
from tests.conftest import cassie, wait_for

pytestmark = [pytest.mark.faults, pytest.mark.slow]

KILLED = ("state_estimator", "torque_bridge", "osc", "mpfc")
#: what the issue asks of a restart: ready again within this long (wall) of the kill
RESTART_S = 1.0


def _walked(status: str) -> float:
    m = re.search(r"walked (-?[0-9.]+) m", status)
    return float(m.group(1)) if m else 0.0


def _save(figures: dict[str, Any]) -> None:
    """The run's figures to ``$CASSIE_FAULTS_JSON``, the mode in the file name, if it is set."""
    if path := os.environ.get("CASSIE_FAULTS_JSON"):
        out = Path(path)
        out.with_stem(f"{out.stem}_{figures['mode']}").write_text(json.dumps(figures, indent=1))


@pytest.fixture(scope="module", params=["lockstep", "realtime"])
def run(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory
        ) -> dict[str, Any]:
    """The suite once in lockstep (a dead process stops sim time) and once in real time
    (the robot keeps falling while a standby takes over, and the watchdogs must hold it)."""
    mode = request.param
    tmp = tmp_path_factory.mktemp(f"live_faults_{mode}")
    url = f"udpm://239.255.76.67:{random.randrange(20000, 60000, 10)}"
    os.environ["CASSIE_LCM_URL"] = url  # (module scope: monkeypatch is per test)
    profile_path = tmp / f"{mode}_faults.yaml"
    profile_path.write_text(f"include: [{HW_CONFIG_DIR / 'sim.yaml'}]\n"
                            f"profile: {mode}_faults\nmode: {mode}\n"
                            "launch: [sim, state_estimator, torque_bridge, osc, mpfc]\n")
    profile = load_profile(profile_path)
    bus = Bus.for_profile(profile, source="fault_test")
    status = bus.subscribe(profile.status_channel, supervisor_status_t)
    # every TIMING, in order: a successor's first one (its ticks counted from 0 again) says
    # when it runs; the supervisor's status comes once a second, too coarse for a 1 s bound
    timing = bus.subscribe(profile.timing_channel, loop_timing_t, policy="each")
    newest = {ch: bus.subscribe(ch, typ) for ch, typ in (
        ("CASSIE_STATE", robot_state_t), ("NETWORK_CASSIE_STATE", robot_state_t),
        ("NETWORK_MPFC_PLAN", mpfc_output_t), ("OSC_TORQUE", torque_command_t))}
    sup = cassie("launch", str(profile_path), "--no-live", "--log", "--log-dir", str(tmp / "logs"))
    lines: list[str] = []  # read as it comes: a full pipe would block the supervisor
    reader = threading.Thread(target=lambda: lines.extend(iter(sup.stdout.readline, "")),
                              daemon=True)
    reader.start()
    figures: dict[str, Any] = {"mode": mode, "restart_s": {}, "walked_m_before_kill": {},
                               "kill_sim_time_s": {}}
    procs: dict[str, Any] = {}

    ticks: dict[str, int] = {}  # the newest ticks_total of each process
    runs_since: dict[str, float] = {}  # when a process's ticks went back (a successor runs)

    def poll() -> None:
        bus.drain(0.05)
        while (t := timing.pop()) is not None:
            if t.ticks_total < ticks.get(t.process, -1):
                runs_since[t.process] = time.monotonic()
            ticks[t.process] = t.ticks_total
        msg = status.latest()
        if msg is not None:
            procs.update({p.name: p for p in msg.processes})
            sim = procs.get("sim")
            if sim is not None and "FELL" in sim.status:  # no use waiting for a walk
                raise AssertionError(f"Cassie fell: {sim.status}")

    def ready(name: str) -> bool:
        p = procs.get(name)
        return p is not None and p.state == "ready"

    try:
        wait_for(lambda: all(ready(n) for n in ("sim", *KILLED)), 300, poll=poll,
                 what="the stack ready")
        wait_for(lambda: _walked(procs["sim"].status) > 0.5, 120, poll=poll,
                 what="Cassie walking half a metre")
        for name in KILLED:
            wait_for(lambda name=name: re.search(r"standby \d+$", procs[name].detail)
                     is not None, 120, poll=poll, what=f"{name}'s standby set up")
            figures["walked_m_before_kill"][name] = _walked(procs["sim"].status)
            pid = procs[name].pid
            state = newest["CASSIE_STATE"].latest()  # (decoded on demand: peek may be None)
            figures["kill_sim_time_s"][name] = state.header.utime * 1e-6 if state else None
            os.kill(pid, signal.SIGKILL)
            t_kill = time.monotonic()
            runs_since.pop(name, None)
            wait_for(lambda name=name: name in runs_since, 60, poll=poll,
                     what=f"{name}'s successor running")
            figures["restart_s"][name] = runs_since[name] - t_kill
            wait_for(lambda pid=pid, name=name: ready(name) and procs[name].pid != pid, 60,
                     poll=poll, what=f"{name} restarted and ready")
            t_walk = _walked(procs["sim"].status)
            wait_for(lambda t_walk=t_walk: _walked(procs["sim"].status) > t_walk + 0.3, 120,
                     poll=poll, what=f"walking on after the kill of {name}")
        # garbage and poison on every LCM input of the stack, and on both UDP ports
        sent: dict[str, int] = {}
        rng = random.Random(7)
        inputs = sorted({ch.name for n in profile.launch
                         for ch in profile.processes[n].inputs.values() if not ch.is_udp})
        for _ in range(20):
            for ch in inputs:
                bus.publish(ch, bytes(rng.randrange(256) for _ in range(rng.randrange(1, 300))))
                sent[ch] = sent.get(ch, 0) + 1
            for ch, field in (("CASSIE_STATE", "q"), ("NETWORK_CASSIE_STATE", "v"),
                              ("NETWORK_MPFC_PLAN", "next_footstep_world"),
                              ("OSC_TORQUE", "torque")):
                good = newest[ch].latest()
                if good is not None:
                    bad = copy.deepcopy(good)
                    vals = list(getattr(bad, field))
                    vals[0] = math.nan
                    setattr(bad, field, vals)
                    bus.publish(ch, bad.encode())
                    sent[ch + " (NaN)"] = sent.get(ch + " (NaN)", 0) + 1
            cmd = command_t()
            cmd.vx, cmd.mode = 1e12, 0
            bus.publish("COMMAND", cmd.encode())
            sent["COMMAND (1e12 m/s)"] = sent.get("COMMAND (1e12 m/s)", 0) + 1
            poll()
            time.sleep(0.05)
        udp = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        for k in range(200):  # a rogue bridge (the default token) and garbage states
            udp.sendto(encode_input(k, 0, [200.0] * 10), profile.channels["robot_input"].udp)
            udp.sendto(bytes(OUTPUT_SIZE), profile.channels["robot_output"].udp)
            time.sleep(0.002)
        udp.close()
        figures["garbage_sent"] = sent
        poisoned = {k for k in sent if k.endswith("(NaN)")}
        assert len(poisoned) == 4, f"NaN copies not sent (no good message to copy?): {sent}"
        figures["rogue_torque_packets"] = 200
        t_walk = _walked(procs["sim"].status)
        wait_for(lambda: _walked(procs["sim"].status) > t_walk + 0.5, 120, poll=poll,
                 what="walking on after the garbage")
        figures["sim_status"] = procs["sim"].status
    finally:
        if sup.poll() is None:
            os.kill(sup.pid, signal.SIGINT)
        sup.wait(timeout=60)
        reader.join(10)
        out = "".join(lines)
        bus.close()
        os.environ.pop("CASSIE_LCM_URL", None)
    figures["summary"] = out[out.find("summary of profile"):]
    _save(figures)
    print(json.dumps({k: v for k, v in figures.items() if k != "summary"}, indent=1))
    print(figures["summary"])
    return {"figures": figures, "out": out, "log": tmp / "logs" / "lcm.log"}


def test_no_kill_or_garbage_knocks_the_robot_over(run):
    summary = run["figures"]["summary"]
    assert "FELL" not in summary, summary
    robot = re.search(r"robot: walked ([0-9.]+) m", summary)
    assert robot and float(robot.group(1)) > 2.0, summary


def test_every_killed_process_is_restarted_within_a_second_and_in_the_summary(run):
    restart = run["figures"]["restart_s"]
    assert set(restart) == set(KILLED)
    slow = {n: round(s, 2) for n, s in restart.items() if s > RESTART_S}
    assert not slow, f"restart slower than {RESTART_S} s: {slow}"
    for name in KILLED:
        line = f"crashed: {name}: 1 time(s), restarted 1 time(s) (1 by its standby)"
        assert line in run["out"], run["out"]


def test_no_nan_torque_reached_the_sim_and_the_garbage_was_counted(run):
    import lcm

    from lcmtypes import applied_input_t

    applied = 0
    last: dict[str, dict[str, float]] = {}  # the newest TIMING counters of each process
    decode_errors: dict[str, int] = {}
    kills = {n: t for n, t in run["figures"]["kill_sim_time_s"].items() if t is not None}
    last_command_us: int | None = None  # the newest applied input from a command
    to_safe_ms: dict[str, float] = {}  # a kill -> the first watchdog torque after it
    for ev in lcm.EventLog(str(run["log"]), "r"):
        if ev.channel == "CASSIE_INPUT":
            m = applied_input_t.decode(ev.data)
            assert all(math.isfinite(x) for x in m.torque)
            applied += 1
            u = m.header.utime
            if m.source == 0:
                last_command_us = u
            elif m.source in (1, 2) and last_command_us is not None:
                before = [(t, n) for n, t in kills.items() if t - 0.05 <= u * 1e-6]
                if before:  # the watchdog after the newest kill before it
                    name = max(before)[1]
                    to_safe_ms.setdefault(name, (u - last_command_us) * 1e-3)
        elif ev.channel == "TIMING":
            t = loop_timing_t.decode(ev.data)
            last[t.process] = dict(zip(t.counter_names, t.counter_values, strict=False))
            decode_errors[t.process] = t.decode_errors_total
    assert applied > 100
    run["figures"]["counters"] = last
    run["figures"]["command_to_watchdog_ms"] = to_safe_ms
    _save(run["figures"])  # (again, with these figures)
    if run["figures"]["mode"] == "realtime":
        # a dead OSC: the bridge's watchdog takes over 10 ms of state time after the last
        # command (CASSIE_INPUT is logged at 200 Hz: one 5 ms step of slack)
        assert to_safe_ms.get("osc", math.inf) <= 15.0, to_safe_ms
    # the rogue bridge's packets: dropped as foreign (a few may be lost in a full buffer)
    assert last["sim"]["commands_foreign"] >= 150, last["sim"]
    assert last["state_estimator"]["packets_rejected"] >= 150, last["state_estimator"]
    # the LCM garbage and poison: rejected at each process's edge, counted; the bridge reads
    # the newest state and torque only when it answers, so its garbage is counted where it
    # lands: bytes that do not decode (the poisoned copies, overwritten in the newest slot
    # by the next good message, or answering no state in lockstep, never reach it)
    for name in ("osc", "mpfc"):
        assert last[name]["inputs_rejected"] > 0, (name, last[name])
    assert decode_errors.get("torque_bridge", 0) > 0, decode_errors
    assert "input message(s) rejected at the edge" in run["figures"]["summary"]
