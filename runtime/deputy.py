"""Deputies: one launch across several machines (procman's sheriff/deputy split).

On the robot the NUC and the target PC are computers of their own: the supervisor on the
laptop cannot fork their processes. A deputy runs on each such host (``cassie deputy --host
nuc``) and does there what the supervisor does at home: it starts, stops and restarts that
host's processes, keeps their standbys and watches them, with the supervisor's own code
(``runtime.supervisor.Supervisor`` restricted to that host). The supervisor marks a host
``deputy: true`` in hosts.yaml and then, instead of forking its processes, tells the host's
deputy what it wants; each process's TIMING still comes to the supervisor directly.

The protocol is procman's, stateless: twice a second the supervisor sends DEPUTY_ORDERS, the
whole wanted state (for each process: run or not, and a run id whose change means restart);
twice a second, and on every change, each deputy sends DEPUTY_STATUS, what runs on its host
(pid, state, restarts, crashes, CPU, memory). A deputy that missed messages, or starts late,
catches up from any one; a supervisor learns everything from one status per host.

Who may order a deputy: every order and status carries an HMAC tag (``runtime.pairing``) of a
key shared by the hosts (``deputy_key``: a file, copied to each host as one copies an ssh key);
a message without it is refused and counted. The launch's pairing token and timing key are
derived from that key and the launch's name, so a deputy's processes sign their TIMING and
stamp their torque packets as the supervisor's own would, and neither secret goes on the bus.

Unlike procman's deputies, a deputy stops its processes when the supervisor has been silent
for ``ORPHAN_S``: a robot's controllers must not walk on without anyone watching them (and a
launch leaves no orphans, on any host).
"""

from __future__ import annotations

import hashlib
import hmac
import os
import secrets
import signal
import sys
import time
from pathlib import Path
from typing import IO, TYPE_CHECKING

from lcmtypes import deputy_orders_t, deputy_status_t
from runtime.bus import NETWORK, Bus
from runtime.errors import ConfigError
from runtime.pairing import message_signed, sign_message
from runtime.port_buffer import worth_logging
from runtime.scheduling import normal_priority, rt_priority

if TYPE_CHECKING:
    from runtime.supervisor import Child, Supervisor

#: the environment variable naming the deputies' key file (default ``DEFAULT_KEY_FILE``)
KEY_FILE_ENV = "CASSIE_DEPUTY_KEY_FILE"
DEFAULT_KEY_FILE = Path.home() / ".config" / "cassie" / "deputy.key"
#: seconds between orders, and between a deputy's status messages
PERIOD_S = 0.5
#: a deputy this long silent is gone (its host down, its network cut): its processes are lost.
#: Not less: measured in real time across namespaces, the NUC's deputy (normal priority, on
#: the NUC's CPU) went over 5 s without a status while the OSC set up there at nice -20
SILENT_S = 15.0
#: a supervisor this long silent is gone: its deputies stop what they run for it
ORPHAN_S = 15.0
REPO_ROOT = Path(__file__).resolve().parent.parent


def key_file() -> Path:
    return Path(os.environ.get(KEY_FILE_ENV) or DEFAULT_KEY_FILE)


def deputy_key(create: bool = True) -> bytes:
    """The hosts' shared key (hex in ``key_file()``), made on first use (mode 0600)."""
    path = key_file()
    if not path.exists():
        if not create:
            raise ConfigError(str(path), "deputy key", "no such file",
                              "the file the supervisor's host made: copy it to this host "
                              f"(or point ${KEY_FILE_ENV} at it)")
        path.parent.mkdir(parents=True, exist_ok=True)
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
        with os.fdopen(fd, "w") as f:
            f.write(secrets.token_hex(32) + "\n")
    try:
        key = bytes.fromhex(path.read_text().strip())
    except ValueError:
        key = b""
    if len(key) < 16:
        raise ConfigError(str(path), "deputy key", "is not a key",
                          "32 or more hex digits (delete the file to make a new one, then copy "
                          "it to every host)")
    return key


def launch_secrets(key: bytes, launch: str) -> tuple[int, bytes]:
    """(pairing token, timing key) of the launch named ``launch``: the same on every host."""
    token = int.from_bytes(hmac.digest(key, b"link:" + launch.encode(), hashlib.sha256)[:4],
                           "little") | 1
    return token, hmac.digest(key, b"timing:" + launch.encode(), hashlib.sha256)


def profile_ref(path: Path) -> str:
    """How orders name a profile: relative to the checkout when inside it (the same checkout
    on every host), else absolute (a shared folder)."""
    p = Path(path).resolve()
    try:
        return str(p.relative_to(REPO_ROOT))
    except ValueError:
        return str(p)


class DeputyLink:
    """The supervisor's side: orders to the deputies, their status into its own records."""

    def __init__(self, sup: Supervisor, key: bytes, launch: str) -> None:
        self.sup = sup
        self.key = key
        self.launch = launch
        self.hosts = sorted({c.remote for c in sup.children.values() if c.remote})
        #: host -> (monotonic time, newest status) of its deputy for this launch
        self.seen: dict[str, tuple[float, deputy_status_t]] = {}
        self.errors: dict[str, str] = {}
        self._last_sent = 0.0
        self._released = False
        sup.bus.subscribe_raw(sup.profile.deputy_status_channel, self._on_status)

    # -- messages ------------------------------------------------------------------------------
    def _on_status(self, _channel: str, data: bytes) -> None:
        try:
            msg = deputy_status_t.decode(data)
        except Exception as exc:
            self.sup.refuse("DEPUTY_STATUS", f"malformed ({type(exc).__name__})")
            return
        if not message_signed(data, self.key):
            self.sup.refuse("DEPUTY_STATUS", f"from host {msg.host!r} without the deputies' "
                             "key (another key file, or spoofed)")
            return
        if msg.host not in self.hosts or msg.launch != self.launch:
            return  # a deputy of another host, idle or serving another launch
        self.seen[msg.host] = (time.monotonic(), msg)
        if msg.error:
            self.errors[msg.host] = msg.error
        for p in msg.processes:
            child = self.sup.children.get(p.name)
            if child is not None and child.remote == msg.host:
                self._mirror(child, p)

    def _mirror(self, child: Child, p: object) -> None:
        """The deputy's view of a process into the supervisor's record of it; readiness,
        health and faults come from the process's own TIMING, as for a local one."""
        pid = int(p.pid)  # type: ignore[attr-defined]
        state = str(p.state)  # type: ignore[attr-defined]
        if pid != child.remote_pid and state in ("starting", "ready"):
            # a new copy (a restart, its standby): ready once its own TIMING comes
            child.new_copy(time.monotonic())
        elif state not in ("starting", "ready") and (child.want or state != "stopping"):
            child.state = state
        child.remote_pid = pid
        for name in ("restarts", "crashes", "exit_code", "cpu_percent", "cpu_s", "rss_mb",
                     "affinity", "priority", "detail"):
            setattr(child, name, getattr(p, name))
        if state in ("failed", "crash_loop"):
            child.ever_failed = True
        if child.crashes:
            child.last_crash = child.detail

    def send(self, force: bool = False, release: bool = False) -> None:
        """The wanted state of every process on a deputy's host (at most every PERIOD_S
        unless ``force``); ``release``: the launch is over, the deputies go idle."""
        now = time.monotonic()
        if not force and now - self._last_sent < PERIOD_S:
            return
        self._last_sent = now
        msg = deputy_orders_t()
        msg.launch = self.launch
        msg.profile = "" if release else profile_ref(self.sup.profile.path)
        msg.log_dir = str(self.sup.log_dir)
        msg.instance = int(os.environ.get("CASSIE_INSTANCE", "0") or 0)
        for name in self.sup.order:
            c = self.sup.children[name]
            if c.remote:
                msg.process.append(name)
                msg.host.append(c.remote)
                msg.run.append(bool(c.want) and not release)
                msg.run_id.append(c.run_id)
        msg.num_processes = len(msg.process)
        self.sup.bus.stamp(self.sup.profile.deputy_orders_channel, msg)
        try:
            self.sup.bus.publish(self.sup.profile.deputy_orders_channel,
                                 sign_message(msg, self.key))
        except OSError:
            pass

    # -- what the supervisor asks of it --------------------------------------------------------
    def wait_for_deputies(self, timeout_s: float, out: IO[str]) -> bool:
        """Every deputy host answering for this launch (its profile loaded, nothing run yet)
        within ``timeout_s``; else a line per host saying what to do, and False."""
        out.write(f"waiting for the deputies on {', '.join(self.hosts)}\n")
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline and not self.sup.stop_requested:
            self.send()
            self.sup.bus.poll_every(0.05)
            if self.errors:
                break
            if all(h in self.seen for h in self.hosts):
                out.write("deputies: " + ", ".join(
                    f"{h} (log {self.seen[h][1].log_dir})" for h in self.hosts) + "\n")
                return True
        for h in self.hosts:
            if h in self.errors:
                out.write(f"deputy on host {h}: {self.errors[h]}\n")
            elif h not in self.seen:
                addr = self.sup.profile.hosts[h].address
                out.write(f"no deputy answered for host {h} ({addr}) within {timeout_s:.0f} s: "
                          f"start one there (`cassie deputy --host {h}`, the same instance and "
                          f"key file {key_file()}), or drop `deputy: true` from hosts.{h}\n")
        return False

    def start(self, child: Child) -> None:
        child.want = True
        child.run_id += 1
        child.new_copy(time.monotonic())
        child.detail = ""
        child.log_path = self.sup.log_dir / f"{child.proc.name}.log"
        self.send(force=True)

    def stop(self, child: Child, timeout_s: float) -> None:
        """Stop ``child`` and wait (up to ``timeout_s``) until its deputy says it has."""
        child.want = False
        child.state = "stopping"
        self.send(force=True)
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            self.sup.bus.poll_every(0.02)
            self.send()
            if child.remote not in self.seen or self.silent(child.remote):
                break  # nobody there to stop it (its own orphan timeout will)
            if child.state not in ("starting", "ready", "stopping", "backoff"):
                break
        child.remote_pid = 0
        if child.state not in ("failed", "crash_loop"):
            child.state = "stopped"

    def silent(self, host: str, now: float | None = None) -> bool:
        seen = self.seen.get(host)
        return seen is None or (now or time.monotonic()) - seen[0] > SILENT_S

    def check(self, now: float) -> None:
        """Orders out on time; a process wanted on a silent deputy's host is lost."""
        self.send()
        for c in self.sup.children.values():
            if c.remote and c.want and c.state in ("starting", "ready") and self.silent(
                    c.remote, now):
                c.state = "failed"
                c.ever_failed = True
                c.detail = (f"the deputy on host {c.remote} has been silent for over "
                            f"{SILENT_S:.0f} s (host down or network cut)")

    def release(self) -> None:
        """The launch is over: the deputies go idle now (not after ORPHAN_S)."""
        if self._released:
            return
        self._released = True
        for _ in range(3):  # (datagrams: say it more than once)
            self.send(force=True, release=True)
            time.sleep(0.02)


class Deputy:
    """A host's side: serves one launch at a time with a ``Supervisor`` of this host only."""

    def __init__(self, host: str, bus_url: str, orders_channel: str, status_channel: str,
                 key: bytes, out: IO[str] | None = None, instance: int = 0) -> None:
        self.host = host
        self.key = key
        self.out = out or sys.stdout
        self.instance = instance
        self.orders_channel = orders_channel
        self.status_channel = status_channel
        self.bus = Bus(bus_url, source=f"deputy-{host}",
                       channel_domains={orders_channel: NETWORK, status_channel: NETWORK})
        self.bus.subscribe_raw(orders_channel, self._on_orders)
        self.sup: Supervisor | None = None
        self.launch = ""
        self.error = ""
        self.refused = 0
        self._wanted: dict[str, tuple[bool, int]] = {}
        self._last_orders = 0.0
        self._last_status = 0.0
        self._changed = False
        self._stop = False
        self._ended: set[str] = set()  # launches served and over: their orders are not news
        self.t0 = time.monotonic()

    def say(self, text: str) -> None:
        self.out.write(f"[deputy {self.host}] {text}\n")
        self.out.flush()

    # -- orders --------------------------------------------------------------------------------
    def _on_orders(self, _channel: str, data: bytes) -> None:
        try:
            msg = deputy_orders_t.decode(data)
        except Exception as exc:
            self._refused(f"malformed orders ({type(exc).__name__})")
            return
        if not message_signed(data, self.key):
            self._refused("orders without the deputies' key (another key file, or spoofed)")
            return
        if msg.launch in self._ended:
            return
        if not msg.profile:  # the launch is over
            if msg.launch == self.launch:
                self.say(f"launch {self.launch} released by the supervisor")
                self._end_launch()
            return
        if msg.launch != self.launch:
            if self.sup is not None:
                self.say(f"a new launch {msg.launch} while serving {self.launch}: ending that")
                self._end_launch()
            self._begin(msg)
        if msg.launch != self.launch:
            return
        self._last_orders = time.monotonic()
        self._wanted = {p: (bool(r), int(i)) for p, h, r, i in
                        zip(msg.process, msg.host, msg.run, msg.run_id, strict=False)
                        if h == self.host}

    def _refused(self, why: str) -> None:
        self.refused += 1
        if worth_logging(self.refused, every=1000):
            self.say(f"ignored #{self.refused}: {why}")

    def _begin(self, msg: deputy_orders_t) -> None:
        """Serve the launch ``msg`` names: load its profile, set up this host's part."""
        from runtime.config import load_profile
        from runtime.supervisor import Supervisor, new_log_dir

        self.launch, self.error = msg.launch, ""
        self._changed = True
        self._last_orders = time.monotonic()
        if msg.instance != self.instance:
            self.error = (f"the launch runs instance {msg.instance}, this deputy instance "
                          f"{self.instance}: start it with --instance {msg.instance}")
            self.say(self.error)
            return
        path = Path(msg.profile)
        path = path if path.is_absolute() else REPO_ROOT / path
        if not path.is_file():
            self.error = (f"no profile {msg.profile} on this host (looked at {path}): the "
                          "same checkout must be on every host")
            self.say(self.error)
            return
        try:
            profile = load_profile(path)
        except ConfigError as exc:
            self.error = f"profile {path}: {exc}"
            self.say(self.error)
            return
        log_dir = Path(msg.log_dir)
        try:
            log_dir.mkdir(parents=True, exist_ok=True)
        except OSError:
            log_dir = new_log_dir(f"{profile.name}-{self.host}")
        token, timing = launch_secrets(self.key, msg.launch)
        self.sup = Supervisor(profile, log_dir=log_dir, out=_Prefixed(self.out, self.host),
                              live_table=False, check_first=False, hosts=(self.host,),
                              secrets=(token, timing))
        self.sup.state = "running"
        self.sup.make_succession_locks()
        if profile.mode == "lockstep":  # (as the supervisor: below every loop, above CFS)
            rt_priority(1)
        self.say(f"serving launch {msg.launch} of profile {profile.name}: "
                 f"{', '.join(self.sup.children) or 'no process on this host'} "
                 f"(logs in {log_dir})")

    def _end_launch(self) -> None:
        if self.sup is not None:
            self.sup.state = "stopping"
            self.sup.shutdown()
            self.sup.bus.close()
            normal_priority()
            self.say(f"launch {self.launch} over: every process on this host stopped")
        if self.launch:
            self._ended.add(self.launch)
        self.sup, self.launch, self.error, self._wanted = None, "", "", {}
        self._changed = True
        self._publish()

    def _apply(self) -> None:
        """Make this host's processes what the orders want."""
        sup = self.sup
        assert sup is not None
        for name, child in sup.children.items():
            run, run_id = self._wanted.get(name, (False, 0))
            if run and run_id != child.run_id:
                if child.popen is not None:  # a new run id while it runs: a restart
                    sup.stop_child(child)
                    child.restarts += 1
                child.run_id = run_id
                child.restart_times.clear()
                sup.start_child(child)
                self._changed = True
            elif not run and (child.popen is not None or child.state == "backoff"):
                sup.stop_child(child)
                child.state = "stopped"
                self._changed = True

    # -- the loop ------------------------------------------------------------------------------
    def _publish(self) -> None:
        msg = deputy_status_t()
        msg.host, msg.launch = self.host, self.launch
        msg.state = "idle" if self.sup is None else self.sup.state
        msg.error = self.error
        msg.uptime_s = time.monotonic() - self.t0
        if self.sup is not None:
            msg.log_dir = str(self.sup.log_dir)
            msg.processes = [p for p in self.sup.status_message().processes
                             if p.name in self.sup.children]
        msg.num_processes = len(msg.processes)
        self.bus.stamp(self.status_channel, msg)
        try:
            self.bus.publish(self.status_channel, sign_message(msg, self.key))
        except OSError:
            pass
        self._last_status = time.monotonic()
        self._changed = False

    def stop(self, *_: object) -> None:
        self._stop = True

    def run(self) -> int:
        """Serve launches until SIGINT or SIGTERM; then stop whatever runs."""
        old = {s: signal.signal(s, self.stop) for s in (signal.SIGINT, signal.SIGTERM)}
        self.say(f"waiting for orders on {self.orders_channel} ({self.bus.url}); key "
                 f"{key_file()}")
        try:
            while not self._stop:
                sup = self.sup
                if sup is not None:
                    sup.wait(0.05)
                else:
                    time.sleep(0.05)
                self.bus.handle_pending()
                now = time.monotonic()
                sup = self.sup
                if sup is not None:
                    self._apply()
                    before = {n: (c.state, c.pid) for n, c in sup.children.items()}
                    sup.supervise(now)
                    sup.note_states()
                    if now - sup.resources.last_sample >= 1.0:
                        sup.sample_resources(now)
                    if before != {n: (c.state, c.pid) for n, c in sup.children.items()}:
                        self._changed = True
                    if now - self._last_orders > ORPHAN_S:
                        self.say(f"no orders from the supervisor for {ORPHAN_S:.0f} s: it is "
                                 "gone; stopping what it started here")
                        self._end_launch()
                if self._changed or now - self._last_status >= PERIOD_S:
                    self._publish()
        finally:
            if self.sup is not None:
                self._end_launch()
            self.bus.close()
            for s, h in old.items():
                signal.signal(s, h)
        return 0


class _Prefixed:
    """The host's supervisor's lines with the host in front (one terminal per deputy)."""

    def __init__(self, out: IO[str], host: str) -> None:
        self.out, self.host = out, host

    def write(self, text: str) -> int:
        for line in text.splitlines():
            self.out.write(f"[deputy {self.host}] {line}\n")
        self.out.flush()
        return len(text)

    def flush(self) -> None:
        self.out.flush()

    def isatty(self) -> bool:
        return False

