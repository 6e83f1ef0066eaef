"""One launch across machines, through their deputies (procman's sheriff/deputy split), with
the machines as network namespaces on this one: the target PC and the NUC each a namespace
with a deputy in it (``cassie deputy --host ...``), the laptop a third with the supervisor;
joined by a bridge, each with its own address, as on the robot's network. The LCM traffic
between them (orders, status, TIMING, the plan) crosses that network, the UDP link between
the target PC and the NUC goes to each host's own address, and each process runs in its
host's namespace. Needs root and ``ip netns``; skipped where they are not available."""

from __future__ import annotations

import os
import random
import re
import shutil
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from runtime.config import HW_CONFIG_DIR
from tests.conftest import REPO

HOSTS = ("target_pc", "nuc", "laptop")


def _ip(*args: str) -> None:
    subprocess.run(["ip", *args], check=True, capture_output=True, text=True)


def _netns_ok() -> str:
    """'' when network namespaces can be made here, else why not."""
    if os.geteuid() != 0:
        return "needs root"
    if shutil.which("ip") is None:
        return "needs iproute2 (ip)"
    name = f"cassie-probe-{os.getpid()}"
    try:
        _ip("netns", "add", name)
        _ip("netns", "del", name)
    except (subprocess.CalledProcessError, OSError) as exc:
        return f"cannot make a network namespace ({exc})"
    return ""


@pytest.fixture
def network() -> Iterator[dict[str, tuple[str, str]]]:
    """host -> (namespace, address): three namespaces on one bridge, multicast routed."""
    why = _netns_ok()
    if why:
        pytest.skip(why)
    sfx = f"{random.randrange(16**4):04x}"
    subnet = f"10.213.{random.randint(1, 250)}"
    bridge = f"cbr{sfx}"
    made: dict[str, tuple[str, str]] = {}
    try:
        _ip("link", "add", bridge, "type", "bridge")
        # (flood multicast to every port: no IGMP querier here to teach the bridge)
        Path(f"/sys/class/net/{bridge}/bridge/multicast_snooping").write_text("0")
        _ip("link", "set", bridge, "up")
        for i, host in enumerate(HOSTS, start=1):
            ns, addr = f"cassie-{host}-{sfx}", f"{subnet}.{i}"
            _ip("netns", "add", ns)
            made[host] = (ns, addr)
            inner, outer = f"cv{i}{sfx}", f"cp{i}{sfx}"
            _ip("link", "add", inner, "type", "veth", "peer", "name", outer)
            _ip("link", "set", outer, "master", bridge)
            _ip("link", "set", outer, "up")
            _ip("link", "set", inner, "netns", ns)
            _ip("-n", ns, "addr", "add", f"{addr}/24", "dev", inner)
            _ip("-n", ns, "link", "set", inner, "up")
            _ip("-n", ns, "link", "set", "lo", "up")
            _ip("-n", ns, "route", "add", "224.0.0.0/4", "dev", inner)
        yield made
    finally:
        for ns, _ in made.values():
            pids = subprocess.run(["ip", "netns", "pids", ns], capture_output=True,
                                  text=True).stdout.split()
            for pid in pids:  # (only if the test failed half-way: ours, never left behind)
                try:
                    os.kill(int(pid), signal.SIGKILL)
                except (ProcessLookupError, ValueError):
                    pass
            subprocess.run(["ip", "netns", "del", ns], capture_output=True)
        subprocess.run(["ip", "link", "del", bridge], capture_output=True)


def _in_ns(ns: str, *args: str, env: dict[str, str]) -> subprocess.Popen[str]:
    return subprocess.Popen(["ip", "netns", "exec", ns, sys.executable, "-m", "tools.cli", *args],
                            cwd=str(REPO), env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True, start_new_session=True)


def _netns_inode(path: str) -> int:
    return os.stat(path).st_ino


class _Lines:
    """A child's output read on a thread (so a full pipe never stalls it), kept for asserts."""

    def __init__(self, proc: subprocess.Popen[str]) -> None:
        self.lines: list[str] = []
        self._t = threading.Thread(target=self._read, args=(proc,), daemon=True)
        self._t.start()

    def _read(self, proc: subprocess.Popen[str]) -> None:
        assert proc.stdout is not None
        for line in proc.stdout:
            self.lines.append(line)

    def text(self) -> str:
        return "".join(self.lines)


class _Across:
    """A launch of the sim profile over the namespaces: the deputies in theirs, the
    supervisor in the laptop's; everything stopped (SIGINT) on ``close``."""

    def __init__(self, network: dict[str, tuple[str, str]], tmp_path: Path, mode: str,
                 duration_s: float) -> None:
        self.network = network
        instance = random.randint(40, 90)
        hosts_yaml = "\n".join(
            f"  {h}: {{address: {addr}, lcm_port_offset: {i}, cpus: [{0 if h != 'nuc' else 1}]"
            f"{', deputy: true' if h != 'laptop' else ''}}}"
            for i, (h, (_ns, addr)) in enumerate(network.items(), start=1))
        profile = tmp_path / "across.yaml"
        profile.write_text(
            "profile: across\n"
            f"include: [{HW_CONFIG_DIR / 'sim.yaml'}]\n"
            f"mode: {mode}\n"
            "launch: [sim, state_estimator, torque_bridge, osc, mpfc]\n"
            f"hosts:\n{hosts_yaml}\n")
        env = dict(os.environ)
        env.pop("CASSIE_LCM_URL", None)  # (the profile's own URL: the namespaces are ours)
        env.update({
            "PYTHONPATH": str(REPO),
            "CASSIE_DEPUTY_KEY_FILE": str(tmp_path / "deputy.key"),
            "CASSIE_SHM_DIR": str(tmp_path / "shm"),
            "PYTHONUNBUFFERED": "1",
        })
        (tmp_path / "shm").mkdir()
        self.deputies = {h: _in_ns(network[h][0], "deputy", "--host", h, "--instance",
                                   str(instance), env=env) for h in ("target_pc", "nuc")}
        self.dep_out = {h: _Lines(p) for h, p in self.deputies.items()}
        time.sleep(1.0)
        self.sheriff = _in_ns(network["laptop"][0], "launch", str(profile), "--duration",
                              str(duration_s), "--instance", str(instance), "--no-live",
                              "--log-dir", str(tmp_path / "logs"), env=env)
        self.out = _Lines(self.sheriff)
        self.deadline = time.monotonic() + 300

    def wait_output(self, pattern: str) -> re.Match[str]:
        """The first match of ``pattern`` in the supervisor's output, waited for."""
        rx = re.compile(pattern, re.M)
        while (m := rx.search(self.out.text())) is None:
            assert time.monotonic() < self.deadline and self.sheriff.poll() is None, (
                self.out.text()[-3000:] + "".join(
                    f"\n--- deputy {h}:\n{d.text()[-2000:]}" for h, d in self.dep_out.items()))
            time.sleep(0.2)
        return m

    def placed(self) -> dict[str, tuple[str, int]]:
        """Process -> (host, pid) from the deputies' lines; each checked to run in its
        host's namespace."""
        placed = {}
        for host in ("target_pc", "nuc"):
            for name, pid in re.findall(r"\] (\w+): \w+ -> starting, pid (\d+)",
                                        self.dep_out[host].text()):
                placed[name] = (host, int(pid))
        assert set(placed) == {"sim", "state_estimator", "torque_bridge", "osc"}, placed
        for name, (host, pid) in placed.items():
            assert _netns_inode(f"/proc/{pid}/ns/net") == _netns_inode(
                f"/run/netns/{self.network[host][0]}"), f"{name} (pid {pid}) not in {host}'s"
        return placed

    def walked(self) -> float:
        text = self.out.text()
        assert "FELL" not in text, text[-3000:]
        assert "ignored" not in text, text[-3000:]  # every order, status and TIMING was signed
        return float(re.findall(r"robot: walked ([\d.]+) m", text)[-1])

    def deputies_idle(self) -> None:
        """The deputies stopped what they ran as the launch ended, and wait for the next."""
        time.sleep(1.0)
        for host, dep in self.deputies.items():
            text = self.dep_out[host].text()
            assert dep.poll() is None, text
            assert "released by the supervisor" in text, text
            left = subprocess.run(["ip", "netns", "pids", self.network[host][0]],
                                  capture_output=True, text=True).stdout.split()
            assert set(left) <= {str(dep.pid)}, (host, left)

    def close(self) -> None:
        for p in [*self.deputies.values(), self.sheriff]:
            if p.poll() is None:
                os.killpg(p.pid, signal.SIGINT)
                try:
                    p.wait(timeout=20)
                except subprocess.TimeoutExpired:
                    os.killpg(p.pid, signal.SIGKILL)
        for host, dep in self.deputies.items():
            assert dep.returncode == 0, self.dep_out[host].text()[-2000:]


def test_a_launch_runs_across_two_deputy_hosts_in_network_namespaces(
        network: dict[str, tuple[str, str]], tmp_path: Path) -> None:
    run = _Across(network, tmp_path, "lockstep", duration_s=12)
    try:
        run.wait_output(r"mpfc: ready")
        placed = run.placed()
        assert run.sheriff.wait(timeout=120) == 0, run.out.text()[-4000:]
        assert "result: ok" in run.out.text(), run.out.text()[-4000:]
        walked = run.walked()
        assert walked > 0.1, run.out.text()[-3000:]  # it walked over the namespaces' wires
        run.deputies_idle()
        print(f"across namespaces: {', '.join(f'{n} on {h}' for n, (h, _) in placed.items())}"
              f", mpfc on laptop; walked {walked:.2f} m")
    finally:
        run.close()


@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason=(
    "known bug (2026-12-03, quiet machine): the NUC's deputy hands the killed bridge over to "
    "its standby at once and the supervisor counts it; the successor drives the robot for "
    "5.6 s; then, as the NUC's deputy starts the bridge's next standby, the OSC sends no "
    "command for over 10 ms, the bridge's watchdog damps and Cassie falls (on one host the "
    "same kill and the same next standby cost nothing). Cause not isolated yet"))
def test_a_kill_on_a_deputy_host_is_taken_over_there_and_counted_by_the_supervisor(
        network: dict[str, tuple[str, str]], tmp_path: Path) -> None:
    """Real time, as on the robot: the bridge killed -9 on the NUC once its spare is set up;
    the NUC's deputy hands over to the spare, the supervisor on the laptop counts the crash
    and restart, and the robot walks on."""
    run = _Across(network, tmp_path, "realtime", duration_s=200)
    try:
        run.wait_output(r"mpfc: ready")
        placed = run.placed()
        run.wait_output(r"^torque_bridge .* standby \d+$")  # (its spare set up: in the table)
        killed = placed["torque_bridge"][1]
        os.kill(killed, signal.SIGKILL)
        # the supervisor's line for the new copy (ready again, a pid not the killed one's)
        run.wait_output(rf"torque_bridge: \w+ -> ready, pid (?!{killed}\b)\d+")
        time.sleep(5.0)
        os.kill(run.sheriff.pid, signal.SIGINT)  # (as a user's Ctrl-C)
        code = run.sheriff.wait(timeout=120)
        text = run.out.text()
        assert code == 1, text[-4000:]  # (a crash of a required process fails the run...)
        assert re.search(r"crashed: torque_bridge: 1 time\(s\), restarted 1 time\(s\)",
                         text), text[-4000:]
        assert "result: FAILED (torque_bridge)" in text, text[-4000:]  # (... nothing else)
        assert "its standby took over" in run.dep_out["nuc"].text(), \
            run.dep_out["nuc"].text()[-3000:]
        walked = run.walked()
        assert walked > 1.0, text[-3000:]
        run.deputies_idle()
        print(f"kill -9 of the bridge on the NUC's namespace: taken over; walked {walked:.2f} m")
    finally:
        run.close()
