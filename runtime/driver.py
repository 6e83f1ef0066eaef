"""Driving one node by hand, tick by tick: the third runner, for tests and benchmarks.

The live runner and the harness give a node its inputs through the same port buffers
(``runtime.bus.Subscription``: decode on read, the newest or each message by the role's
policy, the edge checks) and the same ``PortInbox``; this does too, so a test of a node sees
what a run would, not a hand-made imitation. What the node publishes is kept, decoded (LCM) or
copied (raw packets), per output role; with ``encoded=True`` as the bytes that go on the wire.

    d = NodeDriver(node)            # node.setup(d.ctx) is called
    d.put("state", state_msg)       # as if it arrived on the state role's channel
    d.tick()                        # on the trigger role's message, if one came
    d.tick(state=s, torque=c)       # the same, with these put first (in this order)
    d.sent["torque"][-1]            # what it published
    d = NodeDriver.from_config(proc, profile)   # built, limited and decimated as a run's

The ticks a runner makes: ``tick`` (on the trigger; a periodic node at its next period),
``timeout_tick`` (the trigger timeout passed with nothing) and ``fill_tick`` (a message on
an ``off_slot_wake`` input). ``tick_ns`` and ``tick_cpu_ns`` time the last ``node.tick``
alone, for a benchmark.
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

from runtime.bus import Subscription
from runtime.node import Node, OutputGates
from runtime.port_buffer import PortInbox
from runtime.validate import input_checks

if TYPE_CHECKING:
    from runtime.config_types import ProcessConfig, Profile

#: messages a port keeps (an "each" input never drops in a driven test)
CAPACITY = 1 << 16

_RAW = (bytes, bytearray, memoryview)


class DriverContext:
    """``runtime.node.Context``: publishing keeps the message, the clock is set by the driver."""

    def __init__(self, node: Node, output_rate_hz: Mapping[str, float],
                 encoded: bool = False) -> None:
        self.node = node
        self.now_utime = 0
        self.encoded = encoded
        #: output role -> what was published on it, oldest first
        self.sent: dict[str, list[Any]] = {role: [] for role in node.outputs}
        rates = {r: hz for r, hz in output_rate_hz.items() if r in node.outputs}
        self._gates = OutputGates(rates) if rates else None

    def publish(self, role: str, msg: Any) -> None:
        # (lean: a benchmark's timed tick publishes through here)
        try:
            sent = self.sent[role]
        except KeyError:
            raise KeyError(f"{self.node.name} publishes {role!r}, not one of its outputs "
                           f"({', '.join(self.node.outputs)})") from None
        if self._gates is not None and not self._gates.admit(role, self.now_utime):
            return
        if isinstance(msg, _RAW):
            sent.append(bytes(msg))  # (a reused packet buffer: copied)
        elif self.encoded:  # the wire bytes, as LCM would send them
            sent.append(msg.encode())
        else:  # encoded and decoded, as on the bus: nothing is shared with the node
            sent.append(type(msg).decode(msg.encode()))

    def due(self, role: str) -> bool:
        return self._gates is None or self._gates.due(role, self.now_utime)


class NodeDriver:
    """One node, its inputs put by hand, ticked by hand; see the module docstring."""

    def __init__(self, node: Node, *, limits: Mapping[str, Mapping[str, tuple[float, float]]]
                 | None = None, output_rate_hz: Mapping[str, float] | None = None,
                 setup: bool = True, encoded: bool = False) -> None:
        """``limits``: the process's edge checks (hw_config ``limits``), as the runners apply
        them; every LCM input is checked finite regardless. ``output_rate_hz``: its decimated
        outputs (none by default: every message is kept). ``setup``: call ``node.setup``.
        ``encoded``: keep LCM outputs as their encoded bytes (to compare runs bit for bit,
        or to cost a benchmark's tick what LCM's encode costs and no decode)."""
        self.node = node
        self.ports: dict[str, Subscription] = {}
        for role, typ in node.inputs.items():
            policy = (node.trigger_policy if role == node.trigger_role
                      else node.input_policy.get(role, "newest"))
            self.ports[role] = Subscription(role, None if typ is bytes else typ, policy,
                                            capacity=CAPACITY)
        for role, check in input_checks(node.inputs, limits or {}, node.name,
                                        own=node.validates_own).items():
            self.ports[role].check = check
        self.inbox = PortInbox(self.ports)
        self.ctx = DriverContext(node, output_rate_hz or {}, encoded)
        self.ticks = 0
        #: wall and thread-CPU time of the last ``node.tick`` alone (ns): a benchmark's figure,
        #: without the driver's part (taking the trigger, setting the clock)
        self.tick_ns = self.tick_cpu_ns = 0
        self._next_periodic_utime = 0
        if setup:
            node.setup(self.ctx)

    @classmethod
    def from_config(cls, proc: ProcessConfig, profile: Profile, **kw: Any) -> NodeDriver:
        """``proc``'s node as a run of it builds it (``runtime.builder.build_node``, then its
        period and deadline), with its ``limits`` and ``output_rate_hz`` (``kw``: the rest of
        ``__init__``'s). ``max_rate_hz`` is not applied: every tick asked for is made."""
        from runtime.builder import apply_rates, build_node

        node = build_node(proc, profile)
        apply_rates(node, proc)
        return cls(node, limits=proc.limits, output_rate_hz=proc.output_rate_hz, **kw)

    @property
    def sent(self) -> dict[str, list[Any]]:
        return self.ctx.sent

    def put(self, role: str, msg: Any) -> None:
        """``msg`` arrives on ``role`` (an LCM message is encoded on the way, as on the bus)."""
        if role not in self.ports:
            raise KeyError(f"{self.node.name} has no input {role!r} "
                           f"({', '.join(self.ports) or 'none'})")
        raw = bytes(msg) if isinstance(msg, _RAW) else msg.encode()
        self.ports[role].put(raw)

    def tick(self, utime: int | None = None, **inputs: Any) -> bool:
        """One tick, as a runner makes it: a message-driven node ticks on its trigger role's
        message (the newest, or the oldest waiting with "each") and not at all when none
        came (as the runners: see ``timeout_tick``); a periodic node ticks with no trigger.
        ``inputs``: role=message, put first, in the order given. ``utime``: the tick's sim
        time (default: the trigger's ``header.utime``; a periodic node's k-th tick at k
        periods, as the harness schedules it; else the clock as it stands). Returns whether
        the node ticked."""
        self._put_all(inputs)
        role = self.node.trigger_role
        trigger = None
        if role is not None:
            port = self.ports[role]
            trigger = port.pop() if port.policy == "each" else port.take()
            if trigger is None:
                return False
        elif self.node.period_s:
            if utime is None:
                utime = self._next_periodic_utime
            self._next_periodic_utime = utime + max(1, round(self.node.period_s * 1e6))
        self._tick(trigger, utime)
        return True

    def timeout_tick(self, utime: int | None = None, **inputs: Any) -> None:
        """The tick a runner makes when the trigger timeout passes with nothing on the
        trigger role (``Node.trigger_timeout_s``): ``inbox.trigger()`` is None. ``inputs``
        (other roles) are put first, as ``tick``'s."""
        self._put_all(inputs)
        self._tick(None, utime)

    def fill_tick(self, utime: int | None = None, **inputs: Any) -> bool:
        """The tick the live runner makes (in real time) for a message on an input of
        ``Node.off_slot_wake`` with no trigger: ``inbox.trigger()`` is None, and afterwards
        those inputs count as answered (not fresh), as the runner marks them. ``inputs`` are
        put first. Returns whether one of them had something new (whether the node ticked)."""
        if not self.node.off_slot_wake:
            raise ValueError(f"{self.node.name} has no off_slot_wake input to fill in")
        self._put_all(inputs)
        ports = [self.ports[r] for r in self.node.off_slot_wake]
        if not any(p.fresh for p in ports):
            return False
        self._tick(None, utime)
        for p in ports:
            p.fresh = False
        return True

    def _put_all(self, inputs: Mapping[str, Any]) -> None:
        for role, msg in inputs.items():
            self.put(role, msg)

    def _tick(self, trigger: Any | None, utime: int | None) -> None:
        if utime is not None:
            self.ctx.now_utime = utime
        elif trigger is not None and not isinstance(trigger, _RAW):
            header = getattr(trigger, "header", None)
            if header is not None:
                self.ctx.now_utime = int(header.utime)
        self.inbox.set_trigger(trigger)
        c0 = time.thread_time_ns()
        t0 = time.perf_counter_ns()
        self.node.tick(self.ctx, self.inbox)
        t1 = time.perf_counter_ns()
        self.tick_cpu_ns = time.thread_time_ns() - c0
        self.tick_ns = t1 - t0
        self.ticks += 1
