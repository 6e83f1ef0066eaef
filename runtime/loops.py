"""Running one node live: LCM and UDP ports, wall-clock loops, self-measurement.

Two loop kinds, as on the robot:

* message-driven: wait for the driving input, drain everything queued, and tick once on the
  newest message (stale ones are skipped and counted) -- or once per message for ``each``;
* periodic: absolute deadlines ``t0 + k * period``, one sleep per slot (no spinning: on a 2-core
  machine a spin burns the core another loop needs, and on this VM every timed wake costs
  25-50 us of CPU whatever the method); inputs are drained without waiting at the start of each
  tick. A tick that runs past its slot makes the loop skip the slots it missed rather than catch
  up in a burst, and each skipped slot is counted as an overrun (the node sees the jump in
  ``now_utime`` and may act on it: the sim steps its physics through the missed slots).

A message-driven loop with ``max_rate_hz`` ticks at most once per slot of sim time (the first
trigger of the slot; later ones are counted as rate-skipped) in real time and in the harness;
in a live lockstep run, where the sim waits for an answer to every state, it ticks on each.
Outputs with an ``output_rate_hz`` are published at most once per slot of sim time.

Real-time factor: with ``profile.rtf`` below 1 the wall-clock periods and deadlines stretch by
1 / rtf, so a slow machine runs the same asynchronous stack at, say, half speed.

Deadline misses: a periodic tick misses when it ends after ``scheduled + deadline``; a
message-driven tick misses when it ends more than ``deadline`` after its driving message was
sent (the response time, LCM hop included). Input age is measured at the end of the tick.
"""

from __future__ import annotations

import gc
import logging
import os
import select
import signal
import threading
import time
from typing import Any

from runtime.builder import apply_rates
from runtime.bus import Bus, Subscription
from runtime.checkpoint import StateCheckpoint, checkpoint_path
from runtime.config_types import ChannelConfig, ProcessConfig, Profile
from runtime.node import HEALTH_WARNING, Node, OutputGates, SlotGate, TickGuard
from runtime.pairing import publish_timing, timing_key
from runtime.port_buffer import PortInbox
from runtime.scheduling import apply_scheduling, lock_memory
from runtime.succession import Succession
from runtime.timing import FOREIGN_CLOCK_NS, LoopTimer
from runtime.udp import UdpReceiver, UdpSender, loss_from_env
from runtime.validate import input_checks

log = logging.getLogger(__name__)

Port = Subscription | UdpReceiver

#: a periodic loop sends its TIMING report in a slot only with this much of the slot left
REPORT_ROOM_NS = 300_000


class _Context:
    """Live implementation of ``runtime.node.Context``."""

    def __init__(self, runner: LiveRunner) -> None:
        self._runner = runner
        self.now_utime = 0

    def publish(self, role: str, msg: Any) -> None:
        self._runner._publish(role, msg)

    def due(self, role: str) -> bool:
        return self._runner.out_gates.due(role, self.now_utime)


def settle(proc: ProcessConfig) -> None:
    """The end of a loop's set-up, before real time: its garbage collected and frozen
    (``gc: freeze``) and, for a loop scheduled for real time, its memory locked (no page
    faults in it: a page out while idle, say; not for a loop run inside another program, a
    test's or a benchmark's). A standby does this before it waits: done after its go, the two
    took 140 ms, and a robot whose estimator was killed mid-walk in real time fell."""
    if proc.gc == "freeze":
        gc.collect()
        gc.freeze()
        gc.disable()
    if proc.rt_priority is not None or proc.nice is not None:
        note = lock_memory()
        (log.warning if "failed" in note else log.info)(note)


def _set_timer_slack_ns(ns: int) -> bool:
    """Ask Linux to wake this thread within ``ns`` of a timeout (default slack is 50 us)."""
    try:
        import ctypes

        libc = ctypes.CDLL("libc.so.6", use_errno=True)
        return libc.prctl(29, ns, 0, 0, 0) == 0  # PR_SET_TIMERSLACK
    except OSError:
        return False


def _send_ns(msg: Any) -> int:
    header = getattr(msg, "header", None)
    return int(header.send_mono_ns) if header is not None else 0


def _utime(msg: Any) -> int:
    header = getattr(msg, "header", None)
    return int(header.utime) if header is not None else 0


#: how long a UDP input port may stay taken before the runner gives up binding it
BIND_WAIT_S = 1.0


class LiveRunner:
    """Wires a Node to real LCM channels and UDP sockets and runs its loop until stopped."""

    def __init__(
        self,
        node: Node,
        proc: ProcessConfig,
        profile: Profile,
        bus: Bus | None = None,
    ) -> None:
        self.node = node
        self.proc = proc
        self.profile = profile
        self.bus = bus or Bus.for_profile(profile, source=proc.name)
        self._timing_key = timing_key()  # signs its TIMING (None outside a launch)
        #: triggers whose send time was not this host's clock (see FOREIGN_CLOCK_NS)
        self.timed_from_arrival = 0
        self.stop_event = threading.Event()
        apply_rates(node, proc)
        #: wall seconds per sim second (1 / rtf): periods and deadlines stretch with it
        self.wall_per_sim = 1.0 / profile.rtf if profile.mode == "realtime" else 1.0
        self.ports: dict[str, Port] = {}
        self._udp_out: dict[str, UdpSender] = {}
        self._lcm_out: dict[str, str] = {}
        #: inputs that wake a message-driven loop besides its trigger (``Node.off_slot_wake``)
        self._fill_ports: list[Port] = []
        thin = (
            round(1e6 / proc.max_rate_hz)
            if proc.max_rate_hz and node.trigger_role and profile.mode == "realtime"
            and node.trigger_policy == "newest" and not node.receive_thread
            else None
        )
        for role, typ in node.inputs.items():
            ch = self._channel(role, proc.inputs, "inputs")
            policy = (node.trigger_policy if role == node.trigger_role
                      else node.input_policy.get(role, "newest"))
            if ch.udp is not None:
                # (a standby taking over binds while its killed predecessor still holds the
                # port: the kernel frees it ~10-30 ms into the teardown)
                self.ports[role] = UdpReceiver(ch.udp, policy=policy, drop_ratio=loss_from_env(),
                                               bind_wait_s=BIND_WAIT_S)
            else:
                # only the trigger wakes the loop (and every input wakes a receive thread);
                # the others are read when it ticks. A rate-limited trigger is thinned by the
                # kernel too: the 1 kHz OSC is not even woken by the states it would skip
                wake = role == node.trigger_role or node.receive_thread
                slot_us = thin if role == node.trigger_role else None
                fill_hz = node.off_slot_wake.get(role) if profile.mode == "realtime" else None
                if fill_hz:
                    wake, slot_us = True, round(1e6 / fill_hz)
                self.ports[role] = self.bus.subscribe(
                    ch.name, None if typ is bytes else typ, policy, wake=wake,
                    slot_us=slot_us, second_half=bool(fill_hz),
                )
                if fill_hz:
                    self._fill_ports.append(self.ports[role])
        # the edge: every LCM input checked before the node sees it (runtime.validate)
        for role, check in input_checks(node.inputs, proc.limits, str(proc.source_file),
                                        proc.key("limits"), node.validates_own).items():
            self.ports[role].check = check
        self.guard = TickGuard(node)
        for role in node.outputs:
            ch = self._channel(role, proc.outputs, "outputs")
            if ch.udp is not None:
                self._udp_out[role] = UdpSender(ch.udp)
            else:
                self._lcm_out[role] = ch.name
        self.out_gates = OutputGates(
            {r: hz for r, hz in proc.output_rate_hz.items() if r in node.outputs}
        )
        #: max_rate_hz: off in a live lockstep run, where the sim waits for every answer
        self.rate_gate = (
            SlotGate(proc.max_rate_hz)
            if proc.max_rate_hz and node.trigger_role and profile.mode == "realtime"
            else None
        )
        kind = "message" if node.trigger_role else "periodic"
        self.timer = LoopTimer(
            proc.name,
            node.name,
            kind,
            (node.deadline_s or 0.0) * self.wall_per_sim or None,
            proc.rate_hz,
            report_period_s=1.0 / profile.timing_report_hz,
        )
        self.ctx = _Context(self)
        self.inbox = PortInbox(self.ports)
        self._arrived = threading.Event()  # receive thread -> loop: the trigger is fresh
        # what wakes the loop: the LCM domains it subscribes to, and its UDP sockets (a loop
        # that only publishes on LCM joins no domain at all)
        self._fds = self.bus.filenos() + [
            p.fileno() for p in self.ports.values() if isinstance(p, UdpReceiver)
        ]
        self._poller = select.poll()
        for fd in self._fds:
            self._poller.register(fd, select.POLLIN)
        self._udp_in = [p for p in self.ports.values() if isinstance(p, UdpReceiver)]

    def _channel(self, role: str, table: dict[str, ChannelConfig], section: str) -> ChannelConfig:
        if role not in table:
            from runtime.errors import ConfigError

            raise ConfigError(
                self.proc.source_file,
                self.proc.key(section, role),
                f"process {self.proc.name} needs a channel for its {section[:-1]} role {role!r}",
                allowed=", ".join(sorted(self.profile.channels)),
            )
        return table[role]

    # -- publishing ------------------------------------------------------------------------
    def _publish(self, role: str, msg: Any) -> None:
        if not self.out_gates.admit(role, self.ctx.now_utime):
            return
        sender = self._udp_out.get(role)
        if sender is not None:
            sender.send(msg)
            return
        self.bus.publish(self._lcm_out[role], msg)

    # -- receiving -------------------------------------------------------------------------
    def _poll(self, timeout_s: float) -> None:
        """Wait up to ``timeout_s`` for the trigger (or any input, with a receive thread),
        then read everything waiting: LCM on every domain and every UDP port."""
        ready: set[int] = set()
        if timeout_s > 0:
            if not self._fds:
                self.stop_event.wait(timeout_s)
            else:
                try:
                    ready = {fd for fd, _ in self._poller.poll(timeout_s * 1e3)}
                except InterruptedError:
                    pass
        self.bus.handle_pending(ready)
        for port in self._udp_in:
            port.drain(port.fileno() in ready)

    def _stale_and_errors(self) -> None:
        self.timer.stale_skipped_total = sum(p.stale_skipped for p in self.ports.values())
        self.timer.decode_errors_total = sum(p.decode_errors for p in self.ports.values())

    def _maybe_report(self, now_ns: int) -> None:
        if self.timer.due(now_ns):
            self._report(now_ns)

    def _report(self, now_ns: int) -> None:
        self._stale_and_errors()
        node = self.node
        counters = dict(node.counters())
        rejected = sum(p.rejected for p in self.ports.values())
        counters["inputs_rejected"] = float(rejected)
        counters["tick_errors"] = float(self.guard.errors)
        if self.timed_from_arrival:
            counters["inputs_timed_from_arrival"] = float(self.timed_from_arrival)
        status, health = node.status(), node.health()
        if self.guard.errors:
            status += f" | {self.guard.errors} tick errors, last: {self.guard.last_error}"
            health = max(health, HEALTH_WARNING)
        if rejected:
            last = next((f"{r}: {p.last_rejected}" for r, p in self.ports.items()
                         if p.last_rejected), "")
            status += f" | {rejected} inputs rejected, last {last}"
        msg = self.timer.report(now_ns, status, health, counters)
        msg.header.source = self.proc.name
        publish_timing(self.bus, self.profile.timing_channel, msg, self._timing_key)

    # -- the loops -------------------------------------------------------------------------
    def run(self, duration_s: float | None = None, set_up: bool = False,
            succession: Succession | None = None) -> int:
        """Run until SIGINT/SIGTERM, ``stop()`` or ``duration_s``; returns an exit code.
        ``set_up``: the node's ``setup`` and ``warm_up`` were done already (a standby);
        ``succession``: the process's lock, taken already (a standby that took over)."""
        if succession is None:  # held for the whole run: its standby wakes when it ends
            succession = Succession.for_process(self.proc.name)
            if succession is not None and not succession.hold():
                log.error("%s: another copy of it holds %s: not starting a second one",
                          self.proc.name, succession.path)
                return 3
        self._install_signals()
        _set_timer_slack_ns(1000)
        self._parent = os.getppid()  # (a successor exists only while this parent lives)
        if not set_up:
            self.node.setup(self.ctx)
            self.node.warm_up()
            settle(self.proc)
        self._carry_on()
        # real-time priority only now: set-up work (numba, models) must not starve a core
        for note in apply_scheduling(self.proc, realtime=True):
            (log.warning if "failed" in note else log.info)(note)
        now = time.monotonic_ns()
        self.timer.start(now)
        self._report(now)  # the first TIMING: set up and running (the supervisor's "ready")
        end_ns = time.monotonic_ns() + int(duration_s * 1e9) if duration_s else None
        receiver = None
        if self.node.receive_thread and self.node.trigger_role is not None:
            receiver = threading.Thread(target=self._receive_loop, name=f"{self.proc.name}-rx",
                                        daemon=True)
            receiver.start()
        try:
            if self.node.trigger_role is None:
                self._run_periodic(end_ns)
            else:
                self._run_message(end_ns)
        finally:
            self.stop_event.set()
            if receiver is not None:
                receiver.join(1.0)
            self.node.close()
            ck = self.guard.checkpoint
            if os.getppid() != self._parent:
                # the supervisor is gone (killed: no one removes the launch's state files and
                # no successor will load this one): leave nothing behind in /dev/shm
                if ck is not None:
                    ck.remove()
                if succession is not None:
                    succession.path.unlink(missing_ok=True)
            for s in self._udp_out.values():
                s.close()
            for p in self.ports.values():
                if isinstance(p, UdpReceiver):
                    p.close()
            gc.enable()
        if succession is not None:
            succession.release()  # an ordered end (not an exception): no take-over
        return 0

    def _carry_on(self) -> None:
        """Load the state a predecessor of this process saved in this launch (it crashed and
        this is its standby or restart), and save this one's from now on."""
        arrays = self.node.state_arrays()
        path = checkpoint_path(self.proc.name) if arrays else None
        if path is None:
            return
        try:
            ck = StateCheckpoint(path, arrays)
        except (OSError, ValueError) as exc:
            log.warning("%s: no state checkpoint (%s): a successor will start afresh",
                        self.proc.name, exc)
            return
        if ck.load():
            log.info("%s: carrying on from the state its predecessor saved (%s)",
                     self.proc.name, path)
            self.node.restored()
        self.guard.checkpoint = ck

    def stop(self) -> None:
        self.stop_event.set()

    def _install_signals(self) -> None:
        if threading.current_thread() is not threading.main_thread():
            return
        for sig in (signal.SIGINT, signal.SIGTERM):
            signal.signal(sig, lambda *_: self.stop_event.set())

    def _run_periodic(self, end_ns: int | None) -> None:
        period_s = self.node.period_s or 0.001
        period_ns = int(period_s * self.wall_per_sim * 1e9)
        period_us = round(period_s * 1e6)  # sim time per slot
        deadline_ns = int((self.node.deadline_s or period_s) * self.wall_per_sim * 1e9)
        age_role = next(iter(self.node.inputs), None)
        t0 = time.monotonic_ns()
        k = 0
        timer = self.timer
        report_room_ns = min(REPORT_ROOM_NS, period_ns // 2)
        thread_ns = time.thread_time_ns
        mono_ns = time.monotonic_ns
        while not self.stop_event.is_set():
            scheduled = t0 + k * period_ns
            wait = scheduled - mono_ns()
            while wait > 0:  # one sleep per slot (in pieces of at most 50 ms, to stay stoppable)
                time.sleep(min(wait, 50_000_000) / 1e9)
                wait = scheduled - mono_ns()
                if wait > 0:
                    self._maybe_report(scheduled - wait)
                    if self.stop_event.is_set():
                        return
            start = mono_ns()
            c0 = thread_ns()
            self._poll(0.0)
            self.ctx.now_utime = k * period_us
            self.inbox.set_trigger(None)
            self.guard.tick(self.ctx, self.inbox)
            end = mono_ns()
            cpu = thread_ns() - c0
            age = -1
            if age_role is not None:
                last = self.ports[age_role].peek()
                sent = _send_ns(last) if last is not None else 0
                if sent:
                    age = end - sent
            timer.last_utime = self.ctx.now_utime
            timer.record(start, end, start - scheduled, age, end > scheduled + deadline_ns, cpu)
            k += 1
            next_slot = t0 + k * period_ns
            if end > next_slot:  # fell behind: skip the missed slots, never catch up in a burst
                k_new = (end - t0) // period_ns + 1
                timer.overruns_total += k_new - k
                k = k_new
                next_slot = t0 + k * period_ns
            # the TIMING report (~0.1-0.3 ms) only where the slot has room for it, so that it
            # never makes the next tick late; a loop that never has the room reports anyway
            # once its window is twice as long as asked
            if timer.due(end) and (next_slot - end > report_room_ns
                                   or timer.due(end - timer.report_period_ns)):
                self._report(end)
            if end_ns is not None and end >= end_ns:
                break

    def _receive_loop(self) -> None:
        """The receive thread: take every arriving message into its port buffer while the
        loop's thread ticks, and wake the loop when its trigger input has something new."""
        trigger = self.ports[str(self.node.trigger_role)]
        while not self.stop_event.is_set():
            self._poll(0.05)
            if trigger.fresh:
                self._arrived.set()

    def _run_message(self, end_ns: int | None) -> None:
        role = self.node.trigger_role
        assert role is not None
        port = self.ports[role]
        deadline_ns = int((self.node.deadline_s or 0.0) * self.wall_per_sim * 1e9)
        last_trigger_ns = time.monotonic_ns()
        threaded = self.node.receive_thread
        while not self.stop_event.is_set():
            # read before each wait: a node may adapt it (the sim's ResendTimer); wait no
            # longer than what is left of it, so a wake on something else never stretches it
            timeout_s = self.node.trigger_timeout_s
            if timeout_s is None:
                poll_s = 0.05
            else:
                left_s = timeout_s - (time.monotonic_ns() - last_trigger_ns) * 1e-9
                poll_s = min(0.05, max(left_s, 0.0))
            if threaded:  # the receive thread polls; wait for it to say the trigger is fresh
                self._arrived.wait(poll_s)
                self._arrived.clear()
            else:
                self._poll(poll_s)
            now = time.monotonic_ns()
            triggered = port.fresh
            if triggered:
                if self.node.trigger_policy == "each":
                    if self.node.max_backlog is not None:
                        port.trim(self.node.max_backlog)
                    while port.pending():
                        msg = port.pop()
                        if msg is None:
                            break
                        self._tick_on(msg, port, deadline_ns)
                else:
                    gate = self.rate_gate
                    if gate is not None and isinstance(port, Subscription):
                        u = port.newest_utime()  # skip without decoding (every other state)
                        if u is not None and not gate.open(u):
                            port.discard()
                            self.timer.rate_skipped_total += 1
                            continue
                    msg = port.take()  # None: nothing good came (no tick on an old one)
                    if msg is not None:
                        if gate is None or gate.admit(_utime(msg)):
                            self._tick_on(msg, port, deadline_ns)
                        else:
                            self.timer.rate_skipped_total += 1
                last_trigger_ns = time.monotonic_ns()
            fill = None
            if self._fill_ports:  # (most loops have none: no generator per message for them)
                fill = next((p for p in self._fill_ports if p.fresh), None)
            if fill is not None:
                # a message to fill in (``Node.off_slot_wake``), after the trigger's tick if both
                # came: the node ticks with no trigger, timed like any tick of the loop
                self._tick_on(None, fill, deadline_ns)
                for p in self._fill_ports:
                    p.fresh = False  # answered (or not newer): wait for the next one
                last_trigger_ns = time.monotonic_ns()
            elif (not triggered and timeout_s is not None
                  and now - last_trigger_ns > timeout_s * 1e9):
                self.inbox.set_trigger(None)  # the watchdog's tick
                self.guard.tick(self.ctx, self.inbox)
                last_trigger_ns = time.monotonic_ns()
            now = time.monotonic_ns()
            self._maybe_report(now)
            if end_ns is not None and now >= end_ns:
                break

    def _tick_on(self, msg: Any, port: Port, deadline_ns: int) -> None:
        """One timed tick on ``msg`` (None: no trigger, for the newest message of ``port`` to
        fill in, timed from its arrival)."""
        start = time.monotonic_ns()
        c0 = time.thread_time_ns()
        if msg is None:
            sent = port.last_receive_ns
            utime = (port.newest_utime() if isinstance(port, Subscription) else None) or 0
        else:
            sent = _send_ns(msg) or port.last_receive_ns
            arrived = port.last_receive_ns
            if arrived and not 0 <= arrived - sent <= FOREIGN_CLOCK_NS:
                # not a send time of this host's clock moments ago: a log replayed
                # (lcm-logplayer keeps the recorded stamps) or another host's clock; timed
                # from its arrival here instead, and counted
                sent = arrived
                self.timed_from_arrival += 1
            utime = _utime(msg)
        if utime:
            self.ctx.now_utime = utime
        self.inbox.set_trigger(msg)
        self.guard.tick(self.ctx, self.inbox)
        end = time.monotonic_ns()
        cpu = time.thread_time_ns() - c0
        self.timer.last_utime = self.ctx.now_utime
        missed = deadline_ns > 0 and end - sent > deadline_ns
        self.timer.record(start, end, start - sent, end - sent, missed, cpu)
