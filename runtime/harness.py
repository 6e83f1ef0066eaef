"""The deterministic harness: the same node objects, stepped in sim-time order in one process.

No LCM, no sockets, no wall clock: a message published at sim time t reaches its subscribers at
t (plus an optional modelled latency per node), periodic nodes tick at ``k * period`` of sim
time, and ties are broken by the order events were scheduled. The result therefore depends only
on the nodes and their inputs, never on how busy the machine is -- walking experiments and CI
give the same answer on a 2-core box as on a fast one. Messages are encoded and decoded on the
way, exactly as on the bus, so a node cannot tell the difference (and cannot share objects).
"""

from __future__ import annotations

import dataclasses
import heapq
import time
from collections import defaultdict
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from runtime.builder import apply_rates, build_node
from runtime.bus import Subscription
from runtime.config_types import Profile
from runtime.node import Node, OutputGates, SlotGate, TickGuard
from runtime.port_buffer import PortInbox
from runtime.validate import input_checks

US = 1_000_000
#: an "each" inbox never drops in the harness: a tick is scheduled per message
HARNESS_QUEUE = 1 << 20
#: more events than this at one sim instant means a zero-delay cycle that never advances time
MAX_EVENTS_PER_INSTANT = 100_000


@dataclass
class Binding:
    """A node and the channel names its roles are bound to, plus its modelled compute delay."""

    node: Node
    inputs: Mapping[str, str]
    outputs: Mapping[str, str]
    delay_us: int = 0  # sim time between the trigger and the tick's outputs being visible
    max_rate_hz: float | None = None  # at most one tick per 1/max_rate_hz of sim time
    output_rate_hz: Mapping[str, float] = dataclasses.field(default_factory=dict)
    #: input role -> field -> (lo, hi): the edge checks of ``runtime.validate`` (a live
    #: process's ``limits`` from hw_config); every LCM input is checked finite regardless
    limits: Mapping[str, Mapping[str, tuple[float, float]]] = dataclasses.field(
        default_factory=dict)


class _Context:
    def __init__(self, harness: Harness, index: int) -> None:
        self._h = harness
        self._i = index
        self.now_utime = 0

    def publish(self, role: str, msg: Any) -> None:
        self._h._publish(self._i, role, msg)

    def due(self, role: str) -> bool:
        return self._h._out_gates[self._i].due(role, self.now_utime)


class Harness:
    """Steps bound nodes in sim-time order; see the module docstring."""

    def __init__(self, bindings: list[Binding]) -> None:
        self.bindings = list(bindings)
        self.now_us = 0
        self._events: list[tuple[int, int, int, str, Any]] = []  # (t, order, node, kind, payload)
        self._order = 0
        self._subscribers: dict[str, list[tuple[int, str]]] = defaultdict(list)
        self._ports: list[dict[str, Subscription]] = []
        self._inboxes: list[PortInbox] = []
        self._contexts: list[_Context] = []
        self._pending_tick: list[bool] = []
        self._out_gates: list[OutputGates] = []
        self._rate_gates: list[SlotGate | None] = []
        self._seq: dict[str, int] = defaultdict(int)
        self._taps: dict[str, list[Callable[[int, Any], None]]] = defaultdict(list)
        self.exec_ns: list[list[int]] = []
        #: per binding: ticks so far (a pending timeout fires only if no tick came since)
        self._triggered: list[int] = []
        #: per binding: its ticks' exceptions, caught and counted as in a live process
        self.guards: list[TickGuard] = []
        self.published: dict[str, int] = defaultdict(int)
        for i, b in enumerate(bindings):
            self._bind(i, b)
        self._started = False

    def add(self, binding: Binding) -> None:
        """Bind one more node (before the first ``run_until``)."""
        if self._started:
            raise RuntimeError("add nodes before the harness starts")
        self.bindings.append(binding)
        self._bind(len(self.bindings) - 1, binding)

    # -- observation -----------------------------------------------------------------------
    def tap(self, channel: str, callback: Callable[[int, Any], None]) -> None:
        """Call ``callback(sim_time_us, decoded_msg)`` for every message on ``channel``."""
        self._taps[channel].append(callback)

    def inject(self, channel: str, msg: Any, at_us: int | None = None) -> None:
        """Deliver ``msg`` on ``channel`` at sim time ``at_us`` (default: now), as if published."""
        t = self.now_us if at_us is None else at_us
        self._push(t, -1, "deliver", (channel, _encode(msg)))

    def _bind(self, i: int, b: Binding) -> None:
        ports: dict[str, Subscription] = {}
        for role, typ in b.node.inputs.items():
            if role not in b.inputs:
                raise KeyError(f"{b.node.name}: input role {role!r} is not bound to a channel")
            policy = (b.node.trigger_policy if role == b.node.trigger_role
                      else b.node.input_policy.get(role, "newest"))
            # the same inbox a live subscription fills, so a node cannot tell the difference
            ports[role] = Subscription(
                b.inputs[role], None if typ is bytes else typ, policy, capacity=HARNESS_QUEUE
            )
            self._subscribers[b.inputs[role]].append((i, role))
        for role, check in input_checks(b.node.inputs, b.limits, b.node.name,
                                        own=b.node.validates_own).items():
            ports[role].check = check
        for role in b.node.outputs:
            if role not in b.outputs:
                raise KeyError(f"{b.node.name}: output role {role!r} is not bound to a channel")
        self._ports.append(ports)
        self.guards.append(TickGuard(b.node))
        self._inboxes.append(PortInbox(ports))
        self._contexts.append(_Context(self, i))
        self._pending_tick.append(False)
        self._out_gates.append(OutputGates(
            {r: hz for r, hz in b.output_rate_hz.items() if r in b.node.outputs}))
        self._rate_gates.append(
            SlotGate(b.max_rate_hz) if b.max_rate_hz and b.node.trigger_role else None)
        self.exec_ns.append([])
        self._triggered.append(0)

    # -- running ---------------------------------------------------------------------------
    def start(self) -> None:
        if self._started:
            return
        self._started = True
        for i, b in enumerate(self.bindings):
            b.node.setup(self._contexts[i])
            if b.node.trigger_role is None:
                if not b.node.period_s:
                    raise ValueError(f"{b.node.name}: a periodic node needs period_s")
                self._push(0, i, "periodic", None)

    def run_until(self, t_us: int, stop: Callable[[], bool] | None = None,
                  progress: Callable[[int], None] | None = None,
                  progress_every_us: int = 100_000) -> int:
        """Process every event up to sim time ``t_us``; returns the sim time reached.
        ``progress(now_us)`` is called each time sim time passes another
        ``progress_every_us``, and once at the end: a tool's progress bar (the harness draws
        nothing itself); it must not touch the harness."""
        self.start()
        same_time = 0
        # (checked only when sim time moves on, so a run without it costs nothing per event)
        next_report = self.now_us + progress_every_us if progress is not None else None
        while self._events and self._events[0][0] <= t_us:
            t, _, i, kind, payload = heapq.heappop(self._events)
            if t == self.now_us:
                same_time += 1
                if same_time > MAX_EVENTS_PER_INSTANT:
                    raise RuntimeError(
                        f"no progress in sim time at {t} us after {same_time} events: message-"
                        "driven nodes answer each other with zero delay in a cycle, and no "
                        "periodic node advances time (drive the sim periodically in the harness)"
                    )
            else:
                same_time = 0
                if next_report is not None and t >= next_report:
                    progress(t)  # type: ignore[misc]
                    next_report = t + progress_every_us
            self.now_us = t
            if kind == "deliver":
                self._deliver(*payload)
            elif kind == "periodic":
                self._tick(i, None)
                period_us = round(self.bindings[i].node.period_s * US)  # type: ignore[operator]
                self._push(t + period_us, i, "periodic", None)
            elif kind == "timeout":
                if payload == self._triggered[i]:  # nothing came since: the timeout's tick
                    self._tick(i, None)
            elif kind == "trigger":
                self._pending_tick[i] = False
                self._tick_trigger(i)
            if stop is not None and stop():
                if progress is not None:
                    progress(self.now_us)
                return self.now_us
        self.now_us = max(self.now_us, t_us)
        if progress is not None:
            progress(self.now_us)
        return self.now_us

    def close(self) -> None:
        for b in self.bindings:
            b.node.close()

    @classmethod
    def from_profile(cls, profile: Profile, names: list[str] | None = None,
                     mode: str | None = "lockstep") -> Harness:
        """The profile's processes (or ``names``) built as live (``runtime.builder``) and bound
        to the same channels, each with its configured ``harness_delay_ms``. The harness is a
        lockstep execution, so by default nodes that differ in real time (a sim rendering
        depth in another process, say) are built for lockstep; ``mode="realtime"`` (or None:
        the profile's own) builds their real-time variants, to test those in sim-time order."""
        if mode is not None:
            profile = dataclasses.replace(profile, mode=mode)  # type: ignore[arg-type]
        bindings = []
        for name in names or list(profile.launch):
            proc = profile.processes[name]
            node = build_node(proc, profile)
            apply_rates(node, proc)
            if node.trigger_role is None and node.period_s is None:
                raise ValueError(f"process {name} is periodic but has no rate_hz")
            bindings.append(
                Binding(
                    node,
                    inputs={
                        role: ch.name for role, ch in proc.inputs.items() if role in node.inputs
                    },
                    outputs={
                        role: ch.name for role, ch in proc.outputs.items() if role in node.outputs
                    },
                    delay_us=round(proc.harness_delay_ms * 1000),
                    max_rate_hz=proc.max_rate_hz,
                    output_rate_hz=dict(proc.output_rate_hz),
                    limits=proc.limits,
                )
            )
        return cls(bindings)

    # -- internals -------------------------------------------------------------------------
    def _push(self, t: int, i: int, kind: str, payload: Any) -> None:
        heapq.heappush(self._events, (t, self._order, i, kind, payload))
        self._order += 1

    def _publish(self, i: int, role: str, msg: Any) -> None:
        if not self._out_gates[i].admit(role, self._contexts[i].now_utime):
            return
        channel = self.bindings[i].outputs[role]
        header = getattr(msg, "header", None)
        if header is not None:
            header.seq = self._seq[channel]
            header.send_mono_ns = self.now_us * 1000  # sim time stands in for the monotonic clock
            if not header.source:
                header.source = self.bindings[i].node.name
        self._seq[channel] += 1
        raw = _encode(msg)
        delay = self.bindings[i].delay_us
        if delay:
            self._push(self.now_us + delay, i, "deliver", (channel, raw))
        else:
            self._deliver(channel, raw)

    def _deliver(self, channel: str, raw: bytes) -> None:
        self.published[channel] += 1
        taps = self._taps.get(channel)
        for j, role in self._subscribers.get(channel, ()):
            port = self._ports[j][role]
            node = self.bindings[j].node
            port.put(raw)
            if node.trigger_role == role:
                if port.policy == "each":
                    self._push(self.now_us, j, "trigger", None)
                elif not self._pending_tick[j]:
                    self._pending_tick[j] = True
                    self._push(self.now_us, j, "trigger", None)
        if taps:
            decoded = _decode_for_tap(channel, raw, self)
            for cb in taps:
                cb(self.now_us, decoded)

    def _tick_trigger(self, i: int) -> None:
        node = self.bindings[i].node
        port = self._ports[i][node.trigger_role]  # type: ignore[index]
        msg = port.pop() if port.policy == "each" else port.take()
        if msg is None:
            return
        gate = self._rate_gates[i]
        if gate is not None and port.policy == "newest":
            header = getattr(msg, "header", None)
            if not gate.admit(int(header.utime) if header is not None else self.now_us):
                return
        self._tick(i, msg)

    def _tick(self, i: int, trigger: Any | None) -> None:
        ctx = self._contexts[i]
        if trigger is None:
            ctx.now_utime = self.now_us
        else:
            header = getattr(trigger, "header", None)
            ctx.now_utime = int(header.utime) if header is not None else self.now_us
        inbox = self._inboxes[i]
        inbox.set_trigger(trigger)
        t0 = time.perf_counter_ns()
        self.guards[i].tick(ctx, inbox)
        self.exec_ns[i].append(time.perf_counter_ns() - t0)
        timeout = self.bindings[i].node.trigger_timeout_s
        if timeout and self.bindings[i].node.trigger_role is not None:
            # the node's trigger timeout in sim time: a tick with no trigger if none comes
            # within it (``Node.trigger_timeout_s``); one pending check per tick is enough
            self._triggered[i] += 1
            self._push(self.now_us + max(1, round(timeout * US)), i, "timeout",
                       self._triggered[i])


def _encode(msg: Any) -> bytes:
    return bytes(msg) if isinstance(msg, (bytes, bytearray)) else msg.encode()


def _decode_for_tap(channel: str, raw: bytes, h: Harness) -> Any:
    for j, role in h._subscribers.get(channel, ()):  # a subscriber's type
        typ = h._ports[j][role].msg_type
        return raw if typ is None else typ.decode(raw)  # type: ignore[attr-defined]
    for b in h.bindings:  # nobody subscribes: the publisher's declared type
        for role, name in b.outputs.items():
            if name == channel:
                typ = b.node.outputs[role]
                return raw if typ is bytes else typ.decode(raw)  # type: ignore[attr-defined]
    return raw
