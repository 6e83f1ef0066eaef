"""The supervisor behind ``cassie launch``: starts a profile's processes and keeps them alive.

* Check first: every process's node is built once (``cassie check``: params, gains files,
  channel collisions) before any process starts; a problem ends the launch there, exit 2.
* Standbys: a process with ``restart.standby`` gets a spare once it is ready (``cassie run
  --standby``: set up and warmed up at nice 19, bound to nothing, blocked on stdin); a crash
  is answered by writing ``go`` to the spare, which is ready in a fraction of a second, and a
  new spare is set up a few seconds later, one at a time.
* Start in dependency order; a process is ready when its first TIMING message arrives (every
  loop sends one right after its setup, then about ten a second) within its timeout. The
  supervisor listens to nothing else of the stack: TIMING (and its orders) ride the network
  domain at ~10 Hz per loop, so watching the stack costs no control loop its deadline.
* Each child runs in its own process group (and dies with the supervisor through
  ``PR_SET_PDEATHSIG``); one log file per process.
* A child that exits is restarted per its policy with exponential backoff; more than
  ``max_restarts`` within ``window_s`` puts it in ``crash_loop`` (given up, failed).
* SIGINT/SIGTERM (or ``--duration``) shuts down in reverse order, escalating
  SIGINT -> SIGTERM -> SIGKILL on each process group, so no orphan is left behind.
* Status: a live table on the terminal, and the full state on LCM at 1 Hz, procman-style:
  per process its state, CPU (over one-second windows), memory, loop rate, deadline
  misses, scheduling and the node's own status line (the controller's mode, the robot's
  distance walked); a ``--duration`` run fails when a required process failed or reported a
  fault (a controller in safe mode, a robot that fell). The message, the table and the
  summary are built in ``runtime.supervisor_status``, the CPU and memory figures sampled in
  ``runtime.supervisor_resources``; this module keeps the processes and the main loop.
* ``--log``: every LCM domain into ``LOG_DIR/lcm.log`` (``cassie log``: batched reads with
  kernel arrival times, so recording wakes no control loop's CPU per message).
"""

from __future__ import annotations

import ctypes
import functools
import os
import secrets as _secrets
import select
import signal
import subprocess
import sys
import threading
import time
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

import psutil

from lcmtypes import loop_timing_t, supervisor_orders_t, supervisor_status_t
from runtime import supervisor_status
from runtime.bus import Bus
from runtime.checkpoint import remove_checkpoints
from runtime.config import check_depends
from runtime.config_types import ProcessConfig, Profile, RestartPolicy
from runtime.node import HEALTH_FAULT
from runtime.pairing import TIMING_KEY_ENV, TOKEN_ENV, message_signed
from runtime.port_buffer import worth_logging
from runtime.scheduling import pin_to_supervisor_host, rt_priority
from runtime.succession import create_lock, lock_path
from runtime.supervisor_resources import CpuShare, ResourceSampler
from runtime.supervisor_status import FAILED_STATES

REPO_ROOT = Path(__file__).resolve().parent.parent
#: what SUPERVISOR_ORDERS may ask of a process (or of "*": all)
ORDERS = ("start", "stop", "restart")
#: the standby's "set up" pipe (``cassie run --standby``): the file descriptor it writes
#: ``ready`` to once it waits for the supervisor's go
STANDBY_FD_ENV = "CASSIE_STANDBY_FD"
#: seconds between two standbys' set-ups (one at a time beside the running loops)
STANDBY_SPACING_S = 5.0
_PR_SET_PDEATHSIG = 1


def _child_preexec(cpus: tuple[int, ...] | None = None) -> None:
    """Runs in the child between fork and exec: its own process group, death with the
    supervisor, and (helpers) its CPUs before it starts any thread."""
    os.setpgid(0, 0)
    if cpus:
        try:
            os.sched_setaffinity(0, cpus)
        except OSError:
            pass
    try:
        libc = ctypes.CDLL("libc.so.6", use_errno=True)
        libc.prctl(_PR_SET_PDEATHSIG, signal.SIGTERM)
    except OSError:
        pass


def _stop_group(popen: subprocess.Popen[bytes],
                steps: tuple[tuple[int, float], ...]) -> str:
    """Signal ``popen``'s process group with each (signal, seconds to wait) in turn until it
    exits, then SIGKILL whatever is left in the group; returns the name of the last signal
    it did not stop on ('' if none)."""
    ignored = ""
    for sig, wait_s in steps:
        if popen.poll() is not None:
            break
        try:
            os.killpg(popen.pid, sig)
        except ProcessLookupError:
            pass
        try:
            popen.wait(timeout=wait_s)
        except subprocess.TimeoutExpired:
            ignored = signal.Signals(sig).name
    try:
        os.killpg(popen.pid, signal.SIGKILL)  # the leader is gone: sweep its stragglers
    except ProcessLookupError:
        pass
    return ignored


def logs_home() -> Path:
    """Where launches keep their logs unless told (``--log-dir``): the user's state folder
    (``$XDG_STATE_HOME/cassie/logs``, by default ``~/.local/state/cassie/logs``), not the
    checkout, as ``ros2 launch`` keeps ``~/.ros/log``."""
    base = os.environ.get("XDG_STATE_HOME") or str(Path.home() / ".local" / "state")
    return Path(base) / "cassie" / "logs"


def new_log_dir(profile_name: str) -> Path:
    """A launch's own log folder under :func:`logs_home`, named after its start and profile."""
    return logs_home() / f"{time.strftime('%Y%m%d-%H%M%S')}-{profile_name}"


@dataclass(frozen=True)
class Helper:
    """A supporting program the launch starts before the stack (the logger, the dashboard):
    supervised, never required, no heartbeat; the tools floor says what it runs."""

    name: str
    command: tuple[str, ...]
    nice: int | None = None
    rt_priority: int | None = None


@dataclass
class Child:
    """The supervisor's record of one process."""

    proc: ProcessConfig
    state: str = "stopped"
    popen: subprocess.Popen[bytes] | None = None
    restarts: int = 0
    restart_times: deque[float] = field(default_factory=deque)
    exit_code: int = 0
    next_start_at: float = 0.0
    started_at: float = 0.0
    ready_at: float = 0.0
    backoff_s: float = 0.0
    log_path: Path | None = None
    log_file: IO[bytes] | None = None
    ps: psutil.Process | None = None
    cpu_percent: float = 0.0
    cpu_s: float = 0.0
    rss_mb: float = 0.0
    loop_rate_hz: float = 0.0
    deadline_misses: int = 0
    last_msg_ns: int = 0  # its newest TIMING message (its heartbeat)
    #: the send time of the newest TIMING taken from this copy of it: an older one is a replay
    timing_mark: int = 0
    status: str = ""  # its node's status line, from TIMING
    counters: dict[str, float] = field(default_factory=dict)  # its node's, from TIMING
    health: int = 0
    fault: str = ""  # the first fault it reported (kept: a fall is not undone)
    affinity: str = "not requested"
    priority: str = "not requested"
    detail: str = ""
    ever_failed: bool = False
    crashes: int = 0  # exits with an error or a signal it was not ordered to take
    last_crash: str = ""
    command: list[str] | None = None  # a helper program instead of `cassie run NAME`
    heartbeat: bool = True  # sends TIMING (a Node); else ready once alive for a moment
    #: its spare (``restart.standby``): set up, blocked on stdin until told ``go``
    standby: subprocess.Popen[bytes] | None = None
    standby_pipe: int = -1  # where the spare says it is set up (non-blocking read end)
    standby_ready: bool = False
    takeovers: int = 0  # crashes answered by the standby
    #: the host whose deputy runs it (``runtime.deputy``); "": this supervisor forks it
    remote: str = ""
    want: bool = False  # (remote) wanted running
    run_id: int = 0  # (remote, and a deputy's own record) a new one restarts it
    remote_pid: int = 0  # (remote) its pid, from its deputy's status
    #: its CPU clocks at the last sample (``runtime.supervisor_resources``)
    cpu_share: CpuShare = field(default_factory=CpuShare)

    @property
    def pid(self) -> int:
        return self.popen.pid if self.popen is not None else self.remote_pid

    def new_copy(self, now: float) -> None:
        """A new copy of the process is starting (a start, a standby's take-over, a remote
        restart): nothing its predecessor reported counts for it, and it is ready on its own
        first TIMING."""
        self.state, self.started_at, self.ready_at = "starting", now, 0.0
        self.last_msg_ns, self.status, self.health, self.timing_mark = 0, "", 0, 0

    def alive(self) -> bool:
        if self.remote:
            return self.remote_pid > 0 and self.state in ("starting", "ready")
        return self.popen is not None and self.popen.poll() is None


class Supervisor:
    """Runs a launch profile; see the module docstring."""

    def __init__(
        self,
        profile: Profile,
        log_dir: Path | None = None,
        duration_s: float | None = None,
        out: IO[str] | None = None,
        live_table: bool | None = None,
        extra_args: list[str] | None = None,
        shutdown_grace_s: tuple[float, float] = (3.0, 2.0),
        helpers: Sequence[Helper] = (),
        check_first: bool = True,
        screen: bool = False,
        hosts: tuple[str, ...] | None = None,
        secrets: tuple[int, bytes] | None = None,
    ) -> None:
        """``hosts``: run only the profile's processes on these hosts (a deputy's own);
        ``secrets``: the launch's (pairing token, timing key) when a deputy serves it."""
        self.profile = profile
        #: each process's output also on this terminal, a line at a time with its name in
        #: front (``ros2 launch``'s ``output='screen'``), as well as in its log file
        self.screen = screen
        #: a deputy's supervisor: only its host's processes, orders from the deputy
        self.host_only = hosts is not None
        #: the hosts whose deputies run their processes (hosts.yaml ``deputy: true``)
        remote = () if hosts is not None else tuple(
            h for h, hc in profile.hosts.items() if hc.deputy)
        self.launch_name = _secrets.token_hex(8)
        deputy_key = None
        if remote:  # the secrets then follow from the hosts' shared key (runtime.deputy)
            from runtime.deputy import deputy_key as _deputy_key
            from runtime.deputy import launch_secrets

            deputy_key = _deputy_key()
            secrets = launch_secrets(deputy_key, self.launch_name)
        #: this launch's sim <-> bridge pairing token (runtime.pairing.link_token)
        self.link_token = secrets[0] if secrets else _secrets.randbits(32) | 1
        #: the processes sign their TIMING with it (runtime.pairing); it never goes on the bus
        self.timing_key = secrets[1] if secrets else _secrets.token_bytes(16)
        #: build every node once (``cassie check``) before anything starts
        self.check_first = check_first
        self.log_dir = Path(log_dir) if log_dir else new_log_dir(profile.name)
        self.duration_s = duration_s
        self.out = out or sys.stdout
        self.live_table = (self.out.isatty() if live_table is None else live_table) and not screen
        self.extra_args = extra_args or []
        self.grace = shutdown_grace_s
        self.order = [n for n in check_depends(profile)
                      if hosts is None or profile.processes[n].host in hosts]
        self.children = {name: Child(profile.processes[name],
                                     remote=h if (h := profile.processes[name].host) in remote
                                     else "")
                         for name in self.order}
        self.bus = Bus.for_profile(profile, source="supervisor", recv_buf_size=1 << 20)
        self._all_cpus = tuple(sorted(os.sched_getaffinity(0)))  # children start unpinned
        # the supervisor runs "on the laptop", as procman's sheriff would
        self.home_cpus = pin_to_supervisor_host(profile, hosts[0] if hosts else None)
        for h in helpers or ():
            self._add_helper(h.name, list(h.command), first=True, nice=h.nice,
                             rt_priority=h.rt_priority)
        self.state = "starting"
        self.t0 = time.monotonic()
        #: TIMING messages and orders not taken (malformed, unknown sender or process), by kind
        self.refused: dict[str, int] = {}
        self.refused_last: dict[str, str] = {}
        self.stop_requested = False
        self._next_standby_at = 0.0
        self._noted: dict[str, str] = {}  # the state last printed of each process
        self._noted_pid: dict[str, int] = {}  # ... and its pid
        #: pid -> pidfd of each running child: the main loop wakes on a child's exit
        self._pidfds: dict[int, int] = {}
        self._status_seq = 0
        #: the CPU, memory and scheduling figures of the supervisor and its children
        self.resources = ResourceSampler()
        self.bus.subscribe_raw(profile.timing_channel, self._on_timing)
        #: orders come to the supervisor only (a deputy takes the supervisor's orders)
        if hosts is None:
            self.bus.subscribe_raw(profile.orders_channel, self._on_order)
        self.deputies = None
        if remote:
            from runtime.deputy import DeputyLink

            assert deputy_key is not None
            self.deputies = DeputyLink(self, deputy_key, self.launch_name)

    def _add_helper(self, name: str, command: list[str], first: bool = False,
                    nice: int | None = None, cpus: tuple[int, ...] | None = None,
                    rt_priority: int | None = None) -> None:
        """A supporting program (logger, dashboard): supervised, never required, no heartbeat."""
        proc = ProcessConfig(
            name=name,
            host=self.profile.supervisor_host or "laptop",
            module="",
            source_file=self.profile.path,
            required=False,
            nice=nice,
            rt_priority=rt_priority,
            cpu_affinity=cpus if cpus is not None else getattr(self, "home_cpus", None),
            restart=RestartPolicy(policy="on-failure", max_restarts=3),
        )
        child = Child(proc, command=command, heartbeat=False)
        if first:
            self.children = {name: child, **self.children}
            self.order.insert(0, name)
        else:
            self.children[name] = child
            self.order.append(name)

    # -- bus callbacks -------------------------------------------------------------------------
    def refuse(self, what: str, why: str) -> None:
        """Count a TIMING message or an order that was not taken, and say so (the 1st, 10th,
        100th, then every 1000th)."""
        n = self.refused[what] = self.refused.get(what, 0) + 1
        self.refused_last[what] = why
        if worth_logging(n, every=1000):
            self.out.write(f"ignored {what} #{n}: {why}\n")

    def _decoded(self, msg_type: Any, data: bytes, what: str) -> Any | None:
        """``data`` as a ``msg_type``, or None when it is malformed (refused as ``what``)."""
        try:
            return msg_type.decode(data)
        except Exception as exc:
            self.refuse(what, f"malformed ({type(exc).__name__})")
            return None

    def _on_timing(self, _channel: str, data: bytes) -> None:
        if (msg := self._decoded(loop_timing_t, data, "TIMING")) is None:
            return
        child = self.children.get(msg.process)
        if child is None and self.host_only and msg.process in self.profile.processes:
            return  # a process of this launch on another host (a deputy hears them all)
        if child is None or msg.header.source != child.proc.name:
            self.refuse("TIMING", f"from {msg.header.source!r} for process {msg.process!r}, "
                         "not one this supervisor runs")
            return
        if not message_signed(data, self.timing_key):
            self.refuse("TIMING", f"for process {msg.process!r} without this launch's "
                         "signature (another launch's, or spoofed)")
            return
        if child.popen is None and not (child.remote and child.want):
            return  # a last report of a process being stopped: nothing to take
        if msg.header.send_mono_ns <= child.timing_mark:
            # signed, but not newer than one already taken from this copy of the process: a
            # recorded message sent again (the tag proves the launch, this its freshness)
            self.refuse("TIMING", f"for process {msg.process!r} replayed (sent at "
                         f"{msg.header.send_mono_ns} ns, not after {child.timing_mark} ns)")
            return
        child.timing_mark = msg.header.send_mono_ns
        child.last_msg_ns = time.monotonic_ns()
        if msg.ticks or msg.window_s > 0.5:  # not the set-up heartbeat's empty window
            child.loop_rate_hz = msg.rate_hz
        child.deadline_misses = msg.deadline_misses_total
        child.status = msg.status
        child.counters = dict(zip(msg.counter_names, msg.counter_values, strict=False))
        child.health = msg.health
        if msg.health == HEALTH_FAULT and not child.fault:
            child.fault = msg.status
            self.out.write(f"{child.proc.name} reports a fault: {msg.status}\n")

    def _on_order(self, _channel: str, data: bytes) -> None:
        if (msg := self._decoded(supervisor_orders_t, data, "order")) is None:
            return
        if msg.order not in ORDERS:
            self.refuse("order", f"unknown order {msg.order!r} (known: {', '.join(ORDERS)})")
            return
        if msg.process != "*" and msg.process not in self.children:
            self.refuse("order", f"{msg.order} of unknown process {msg.process!r}")
            return
        targets = list(self.children) if msg.process == "*" else [msg.process]
        for name in targets:
            child = self.children.get(name)
            if child is None:
                continue
            if msg.order == "stop":
                self.stop_child(child)
                child.state = "stopped"
            elif msg.order == "start" and child.alive():
                child.detail = "start ordered while running: ignored (order restart instead)"
            elif child.remote and self.deputies is not None:  # its deputy counts a restart
                self.deputies.start(child)
            elif msg.order in ("start", "restart"):
                if msg.order == "restart" and child.popen is not None:
                    self.stop_child(child)
                    child.restarts += 1
                child.restart_times.clear()
                self.start_child(child)

    # -- process control -----------------------------------------------------------------------
    def _command(self, child: Child) -> list[str]:
        if child.command is not None:
            return child.command
        return [
            sys.executable,
            "-m",
            "runtime.run",
            child.proc.name,
            "--profile",
            str(self.profile.path),
            *self.extra_args,
        ]

    def _child_env(self) -> dict[str, str]:
        env = dict(os.environ)
        env["PYTHONPATH"] = os.pathsep.join([str(REPO_ROOT), env.get("PYTHONPATH", "")]).rstrip(
            os.pathsep
        )
        # (before the instance offset: each child moves it by its $CASSIE_INSTANCE itself)
        env["CASSIE_LCM_URL"] = self.profile.base_lcm_url or self.profile.lcm_url
        env["PYTHONUNBUFFERED"] = "1"
        env["CASSIE_SUPERVISED"] = "1"
        # the sim takes torque packets only with this launch's token: a bridge of another
        # run or stack (or any tool) cannot command the robot (docs/udp_protocol.md)
        env[TOKEN_ENV] = str(self.link_token)
        env[TIMING_KEY_ENV] = self.timing_key.hex()
        # one thread per process: numpy's OpenBLAS starts a worker per core at import, which
        # the loops' small matrices never use; unpinned and at normal priority beside the
        # real-time loops, that idle thread took ~50 ms to die on a kill -9 (the process is
        # gone, and its standby told, only once every thread is), and Cassie fell
        for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
            env.setdefault(var, "1")
        return env

    def _spawn(self, child: Child, cmd: list[str], stdin: int,
               ready_fd: int | None = None) -> subprocess.Popen[bytes]:
        """Start ``cmd`` for ``child``: its log file, its own process group, death with the
        supervisor (``ready_fd``: a standby's end of its "set up" pipe)."""
        env = self._child_env()
        if ready_fd is not None:
            env[STANDBY_FD_ENV] = str(ready_fd)
        popen = subprocess.Popen(
            cmd,
            stdout=subprocess.PIPE if self.screen else child.log_file,
            stderr=subprocess.STDOUT,
            stdin=stdin,
            cwd=str(REPO_ROOT),
            env=env,
            pass_fds=() if ready_fd is None else (ready_fd,),
            preexec_fn=functools.partial(
                _child_preexec,
                (child.proc.cpu_affinity or self._all_cpus) if child.command is not None
                else self._all_cpus,  # `cassie run` pins itself to its host's CPUs
            ),
        )
        if self.screen:
            assert popen.stdout is not None and child.log_file is not None
            threading.Thread(target=self._relay, args=(child.proc.name, popen.stdout,
                                                        child.log_file),
                             name=f"relay-{child.proc.name}", daemon=True).start()
        return popen

    def _relay(self, name: str, pipe: IO[bytes], log_file: IO[bytes]) -> None:
        """A child's output, line by line, into its log file and onto the terminal."""
        for line in iter(pipe.readline, b""):
            try:
                log_file.write(line)
            except (ValueError, OSError):  # the launch is over and the file closed
                pass
            self.out.write(f"[{name}] {line.decode(errors='replace').rstrip()}\n")
        pipe.close()

    # -- standbys ------------------------------------------------------------------------------
    def _keep_standbys(self, now: float) -> None:
        """Give each ready process with ``restart.standby`` a spare, one set-up at a time
        (each is a few seconds of a core at nice 19: never two at once beside the loops)."""
        if self.state != "running" or now < self._next_standby_at:
            return
        for name in self.order:
            c = self.children[name]
            if not c.proc.restart.standby or c.command is not None or c.remote:
                continue
            if c.standby is not None and c.standby.poll() is not None:
                self.out.write(f"{name}: its standby exited ({c.standby.returncode}); "
                               "starting another\n")
                self._end_standby(c)
            if c.standby is not None and not c.standby_ready:
                try:
                    c.standby_ready = os.read(c.standby_pipe, 16).startswith(b"ready")
                except BlockingIOError:
                    pass
                if not c.standby_ready:
                    return  # still setting up: one at a time
            if c.standby is None and c.state == "ready" and now - c.ready_at > 1.0:
                assert c.log_file is not None
                c.log_file.write(f"\n=== standby {time.strftime('%H:%M:%S')} ===\n".encode())
                r, w = os.pipe()
                os.set_blocking(r, False)
                try:
                    c.standby = self._spawn(c, [*self._command(c), "--standby"],
                                            subprocess.PIPE, ready_fd=w)
                finally:
                    os.close(w)
                c.standby_pipe, c.standby_ready = r, False
                self._next_standby_at = now + STANDBY_SPACING_S
                return

    def make_succession_locks(self) -> None:
        """One robust mutex per process with a standby (``runtime.succession``): the running
        copy holds it, the standby wakes the moment that copy dies, ~30-50 ms before its exit
        shows here."""
        for name, c in self.children.items():
            if c.proc.restart.standby and c.command is None and not c.remote:
                path = lock_path(name, self.link_token)
                if path is None:
                    return
                try:
                    create_lock(path)
                except OSError as exc:
                    self.out.write(f"{name}: no succession lock ({exc}): its standby learns "
                                   "of a crash only from the supervisor\n")

    def _take_over(self, child: Child, now: float, how: str) -> bool:
        """The crashed ``child``'s standby becomes it (``go`` on its stdin); False when there
        is none alive."""
        sb = child.standby
        if sb is None or sb.poll() is not None or self.state != "running":
            if sb is not None:
                self._end_standby(child)
            return False
        try:
            assert sb.stdin is not None
            sb.stdin.write(b"go\n")  # (a spare still setting up runs once it is set up)
            sb.stdin.flush()
        except OSError:
            self._end_standby(child)
            return False
        child.standby = None
        if child.standby_pipe >= 0:
            os.close(child.standby_pipe)
            child.standby_pipe = -1
        child.popen = sb
        child.new_copy(now)
        child.takeovers += 1
        child.detail = f"{how}; its standby took over"
        try:
            child.ps = psutil.Process(sb.pid)
        except psutil.Error:
            child.ps = None
        self._next_standby_at = max(self._next_standby_at, now + STANDBY_SPACING_S)
        return True

    @staticmethod
    def _end_standby(child: Child) -> None:
        """Stop ``child``'s spare: stdin closed (it exits when it reads the end), its group
        signalled."""
        sb, child.standby, child.standby_ready = child.standby, None, False
        if child.standby_pipe >= 0:
            os.close(child.standby_pipe)
            child.standby_pipe = -1
        if sb is None:
            return
        try:
            if sb.stdin is not None:
                sb.stdin.close()
        except OSError:
            pass
        _stop_group(sb, ((signal.SIGTERM, 2.0), (signal.SIGKILL, 2.0)))

    def start_child(self, child: Child) -> None:
        """Start ``child`` (its deputy does, for a remote one): log file, process, record."""
        self.log_dir.mkdir(parents=True, exist_ok=True)
        if child.remote and self.deputies is not None:
            self.deputies.start(child)
            return
        child.log_path = self.log_dir / f"{child.proc.name}.log"
        if child.log_file is None:
            child.log_file = open(child.log_path, "ab", buffering=0)  # noqa: SIM115
        child.log_file.write(
            f"\n=== start {time.strftime('%H:%M:%S')} (restart {child.restarts}) ===\n".encode()
        )
        child.popen = self._spawn(child, self._command(child), subprocess.DEVNULL)
        child.new_copy(time.monotonic())
        child.detail = ""
        try:
            child.ps = psutil.Process(child.popen.pid)
        except psutil.Error:
            child.ps = None
        if child.command is not None:  # a helper program (`cassie run` applies its own)
            try:
                if child.proc.nice is not None:
                    os.setpriority(os.PRIO_PROCESS, child.pid, child.proc.nice)
            except OSError:
                pass
            rt_priority(child.proc.rt_priority, child.pid)  # (a failure leaves it at its nice)

    def _signal_group(self, child: Child, sig: int) -> None:
        if child.popen is None:
            return
        try:
            os.killpg(child.popen.pid, sig)
        except ProcessLookupError:
            pass

    def stop_child(self, child: Child) -> None:
        """SIGINT, then SIGTERM, then SIGKILL to the child's process group; its standby
        first, which would otherwise take over from a copy stopped on purpose."""
        self._end_standby(child)
        if child.remote and self.deputies is not None:
            self.deputies.stop(child, sum(self.grace) + 3.0)
            return
        if child.popen is None:
            return
        child.state = "stopping"
        ignored = _stop_group(child.popen, ((signal.SIGINT, self.grace[0]),
                                            (signal.SIGTERM, self.grace[1]),
                                            (signal.SIGKILL, 2.0)))
        if ignored:
            child.detail = f"did not stop on {ignored}"
        child.exit_code = child.popen.returncode if child.popen.returncode is not None else 0
        child.popen = None
        child.ps = None

    # -- the main loop -------------------------------------------------------------------------
    def request_stop(self, *_: object) -> None:
        self.stop_requested = True

    def run(self) -> int:
        """Start everything, supervise until stopped, shut down; exit code 0 when all is well."""
        old = {s: signal.signal(s, self.request_stop) for s in (signal.SIGINT, signal.SIGTERM)}
        if self.profile.mode == "lockstep":
            # the loops run flat out at FIFO there, and a launch across deputies must keep
            # its orders flowing: measured, at normal priority beside a lockstep MPFC the
            # supervisor sent none for 5 s and its deputies stopped everything; at the lowest
            # FIFO priority it is still below every loop
            rt_priority(1)
        try:
            if not self._precheck():
                self.state = "stopped"
                return 2
            self.make_succession_locks()
            ok = self._start_all()
            self.state = "running" if ok else "stopping"
            # --duration counts the whole stack running: a fresh clone's start-up (a minute or
            # two of numba compiling) must not eat the walk
            t_running = time.monotonic()
            last_status = 0.0
            last_table = 0.0
            while ok and not self.stop_requested:
                self.wait(0.1)
                now = time.monotonic()
                self.supervise(now)
                self.note_states()
                if now - last_status >= 1.0:
                    self.sample_resources(now)
                    self.publish_status()
                    last_status = now
                if now - last_table >= (0.5 if self.live_table else 5.0):
                    self._print_table(live=self.live_table)
                    last_table = now
                if self.duration_s is not None and now - t_running >= self.duration_s:
                    break
                if self._required_failed():
                    self.out.write("a required process failed; shutting down\n")
                    break
        finally:
            for fd in self._pidfds.values():
                os.close(fd)
            self._pidfds.clear()
            self.state = "stopping"
            self.shutdown()
            self.state = "stopped"
            self.publish_status()
            for s, h in old.items():
                signal.signal(s, h)
        self._print_summary()
        return 1 if self._required_failed() or self._faults() or self._crashed() else 0

    def wait(self, period_s: float) -> None:
        """Sleep ``period_s``, or less when a running child exits (its pidfd turns readable),
        then read the bus in one batch (no publisher ever wakes the supervisor). Measured: at
        a fixed 0.1 s, a killed estimator's standby took over ~100 ms after the kill, and a
        robot walking in real time fell; now within a few ms."""
        watched = {c.popen.pid for c in self.children.values()
                   if c.popen is not None and c.state in ("starting", "ready")}
        for pid in [p for p in self._pidfds if p not in watched]:
            os.close(self._pidfds.pop(pid))
        for pid in watched - self._pidfds.keys():
            try:
                self._pidfds[pid] = os.pidfd_open(pid)
            except OSError:  # gone already (its poll() says so) or no pidfd on this kernel
                pass
        if self._pidfds:
            select.select(list(self._pidfds.values()), [], [], period_s)
        else:
            time.sleep(period_s)
        self.bus.handle_pending()

    def _required_failed(self) -> bool:
        """Whether a required process failed: the launch ends, and the run fails."""
        return bool(supervisor_status.required_failed(self.children.values()))

    def _crashed(self) -> list[str]:
        """Required processes that crashed at least once (the run fails even if a restart
        kept it going)."""
        return supervisor_status.crashed(self.children.values())

    def _faults(self) -> list[str]:
        """Required processes that reported a fault (safe mode, a fall) at any time."""
        return supervisor_status.faulted(self.children.values())

    def _precheck(self) -> bool:
        """Build every process's node once (``cassie check``, in a child: the supervisor
        itself imports no robot code) before anything starts: a bad param, gains file or
        channel collision stops the launch here, on the terminal."""
        if not self._check_processes():
            return False
        if self.deputies is not None and not self.deputies.wait_for_deputies(30.0, self.out):
            self.out.write("result: FAILED (deputies: nothing was started)\n")
            self.out.flush()
            return False
        return True

    def _check_processes(self) -> bool:
        names = [n for n in self.order if self.children[n].command is None]
        if not names or not self.check_first:
            return True
        cmd = [sys.executable, "-m", "runtime.check", str(self.profile.path)]
        for n in names:
            cmd += ["--process", n]
        t0 = time.monotonic()
        try:
            res = subprocess.run(cmd, cwd=str(REPO_ROOT), env=self._child_env(),
                                 capture_output=True, text=True, timeout=300)
        except subprocess.TimeoutExpired:
            self.out.write("checking the profile's processes took over 300 s; not started\n")
            return False
        if res.returncode == 0:
            self.out.write(f"checked {len(names)} processes' params, gains and channels in "
                           f"{time.monotonic() - t0:.1f} s\n")
            return True
        self.out.write(res.stdout + res.stderr)
        self.out.write(f"result: FAILED (configuration: nothing was started; fix the file "
                       f"named above, then `cassie check {self.profile.path}`)\n")
        self.out.flush()
        return False

    def _start_all(self) -> bool:
        self._noted = {n: c.state for n, c in self.children.items()}
        for name in self.order:
            child = self.children[name]
            self.start_child(child)
            self.note_states()
            if not self._wait_ready(child):
                self.note_states()
                return False
            self.out.write(f"{name}: ready in {child.ready_at - child.started_at:.1f} s\n")
            self._noted[name] = child.state
        return True

    def note_states(self) -> None:
        """One line per process whose state changed since the last call: the start-up and
        every crash, restart or take-over show as they happen, not at the next table."""
        for name, child in self.children.items():
            pid = child.pid
            # a new copy in the same state is news too: a deputy's standby that took over
            # between two of its status messages shows here as ready -> ready with a new pid
            replaced = bool(self._noted_pid.get(name)) and pid and self._noted_pid[name] != pid
            if self._noted.get(name) != child.state or replaced:
                was = self._noted.get(name, "-")
                self._noted[name] = child.state
                why = f" ({child.detail})" if child.detail else ""
                pid_text = f", pid {pid}" if pid else ""
                self.out.write(f"[{time.monotonic() - self.t0:6.1f} s] {name}: {was} -> "
                               f"{child.state}{pid_text}{why}\n")
            if pid:
                self._noted_pid[name] = pid

    def _wait_ready(self, child: Child) -> bool:
        deadline = time.monotonic() + child.proc.ready_timeout_s
        last_status = 0.0
        waited_note = time.monotonic() + 10.0
        while time.monotonic() < deadline and not self.stop_requested:
            self.bus.poll_every(0.05)
            now = time.monotonic()
            if now - last_status >= 1.0:  # the status goes on while processes start
                self.sample_resources(now)
                self.publish_status()
                last_status = now
            if self.deputies is not None:
                self.deputies.check(now)
                if child.remote and child.state in FAILED_STATES:
                    return not child.proc.required
            if now >= waited_note:  # a minute of numba compiling must not look like a hang
                waited_note = now + 10.0
                self.out.write(f"{child.proc.name}: still setting up after "
                               f"{now - child.started_at:.0f} s (ready within "
                               f"{child.proc.ready_timeout_s:.0f} s; its log: "
                               f"{child.log_path})\n")
            if child.popen is not None and child.popen.poll() is not None:
                child.detail = f"exited with {child.popen.returncode} before it was ready"
                child.exit_code = child.popen.returncode
                child.state = "failed"
                child.ever_failed = True
                return not child.proc.required
            if child.last_msg_ns or (not child.heartbeat and now - child.started_at > 0.5):
                child.state = "ready"
                child.ready_at = now
                return True
        if self.stop_requested:
            return False
        child.detail = (
            f"no TIMING heartbeat within {child.proc.ready_timeout_s:.1f} s (see its log "
            f"{child.log_path})"
        )
        child.state = "failed"
        child.ever_failed = True
        return not child.proc.required

    def supervise(self, now: float) -> None:
        """One pass over the records: readiness, exits (restart, standby, give up), backoffs
        due, the standbys kept."""
        if self.deputies is not None:
            self.deputies.check(now)
        for child in self.children.values():
            if child.remote:  # its deputy restarts it; ready on its own TIMING, as here
                if child.state == "starting" and child.last_msg_ns:
                    child.state, child.ready_at = "ready", now
                continue
            if child.state in ("starting", "ready") and child.popen is not None:
                code = child.popen.poll()
                if child.state == "starting" and child.last_msg_ns:
                    child.state, child.ready_at = "ready", now
                if code is not None:
                    self._on_exit(child, code, now)
            elif child.state == "backoff" and now >= child.next_start_at:
                self.start_child(child)
            if (child.state == "starting" and not child.heartbeat
                    and now - child.started_at > 0.5):
                child.state, child.ready_at = "ready", now
        self._keep_standbys(now)

    def _on_exit(self, child: Child, code: int, now: float) -> None:
        # The leader is gone; whatever it left in its process group goes with it.
        self._signal_group(child, signal.SIGKILL)
        child.exit_code = code
        child.popen = None
        child.ps = None
        policy = child.proc.restart
        how = f"killed by {signal.Signals(-code).name}" if code < 0 else f"exited with {code}"
        if code != 0:
            child.crashes += 1  # restarted or not, the run is no longer a clean one
            child.last_crash = how
        if policy.policy == "never" or (policy.policy == "on-failure" and code == 0):
            self._end_standby(child)  # (it may have taken over: it must not run untracked)
            child.state = "exited" if code == 0 else "failed"
            child.ever_failed = child.ever_failed or code != 0
            child.detail = how
            return
        while child.restart_times and now - child.restart_times[0] > policy.window_s:
            child.restart_times.popleft()
        if len(child.restart_times) >= policy.max_restarts:
            self._end_standby(child)
            child.state = "crash_loop"
            child.ever_failed = True
            child.detail = (
                f"{how}; {len(child.restart_times)} restarts within "
                f"{policy.window_s:.0f} s: giving up"
            )
            return
        child.restart_times.append(now)
        child.restarts += 1
        if self._take_over(child, now, how):
            return
        n = len(child.restart_times)
        child.backoff_s = min(policy.backoff_initial_s * 2 ** (n - 1), policy.backoff_max_s)
        child.next_start_at = now + child.backoff_s
        child.state = "backoff"
        child.detail = f"{how}; restart in {child.backoff_s:.1f} s"

    def sample_resources(self, now: float) -> None:
        """CPU share (nanosecond CPU clocks over the time since the previous sample: about a
        second, so the figure is a real average, not a 1 ms glimpse), CPU seconds, memory,
        scheduling (``runtime.supervisor_resources``)."""
        self.resources.sample(self.children.values(), now)

    def shutdown(self) -> None:
        """Stop everything in reverse start order (spares first), close the logs, release
        the deputies and remove the processes' saved states."""
        for child in self.children.values():  # the spares first: nothing may take over now
            self._end_standby(child)
        for name in reversed(self.order):
            child = self.children[name]
            if child.popen is not None or (child.remote and child.want):
                was = child.state
                self.stop_child(child)
                child.state = "stopped" if was not in FAILED_STATES else was
            elif child.state in ("backoff", "starting", "ready"):
                child.state = "stopped"
            if child.log_file is not None:
                child.log_file.close()
                child.log_file = None
        if self.deputies is not None:
            self.deputies.release()
        remove_checkpoints(self.link_token)  # the processes' saved states (runtime.checkpoint)

    # -- reporting (runtime.supervisor_status) -------------------------------------------------
    def status_message(self) -> supervisor_status_t:
        """The launch's state as SUPERVISOR_STATUS carries it."""
        return supervisor_status.status_message(self)

    def publish_status(self) -> None:
        """SUPERVISOR_STATUS on the bus (a send error is the next second's to retry)."""
        try:
            self.bus.publish(self.profile.status_channel, self.status_message())
        except OSError:
            pass

    def table(self) -> str:
        """The status table's text."""
        return supervisor_status.table(self)

    def robot_lines(self) -> list[str]:
        """The summary's ``robot:`` and ``controller:`` lines."""
        return supervisor_status.robot_lines(self.children.values())

    def _print_table(self, live: bool) -> None:
        """The table on the terminal: redrawn in place when ``live``, else appended."""
        text = supervisor_status.screen_text(self)
        if live:
            self.out.write("\x1b[H\x1b[J" + text)
        else:
            self.out.write(text)
        self.out.flush()

    def _print_summary(self) -> None:
        """The end-of-launch summary on the terminal."""
        self.out.write(supervisor_status.summary_text(self))
        self.out.flush()
