"""Driving one node by hand, tick by tick: the third runner, for tests and benchmarks.

The live runner and the harness give a node its inputs through the same port buffers
(``runtime.bus.Subscription``: decode on read, the newest or each message by the role's
policy, the edge checks) and the same ``PortInbox``; this does too, so a test of a node sees
what a run would, not a hand-made imitation. What the node publishes is kept, decoded (LCM) or
copied (raw packets), per output role.

    d = NodeDriver(node)            # node.setup(d.ctx) is called
    d.put("state", state_msg)       # as if it arrived on the state role's channel
    d.tick()                        # on the trigger role's message, if one came
    d.sent["torque"][-1]            # what it published
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Mapping
from typing import Any

from runtime.bus import Subscription
from runtime.node import Node, OutputGates
from runtime.port_buffer import PortInbox
from runtime.validate import input_checks

#: messages a port keeps (an "each" input never drops in a driven test)
CAPACITY = 1 << 16


class DriverContext:
    """``runtime.node.Context``: publishing keeps the message, the clock is set by the driver."""

    def __init__(self, node: Node, output_rate_hz: Mapping[str, float]) -> None:
        self.node = node
        self.now_utime = 0
        self.sent: dict[str, list[Any]] = defaultdict(list)
        self._gates = OutputGates({r: hz for r, hz in output_rate_hz.items()
                                   if r in node.outputs})

    def publish(self, role: str, msg: Any) -> None:
        if role not in self.node.outputs:
            raise KeyError(f"{self.node.name} publishes {role!r}, not one of its outputs "
                           f"({', '.join(self.node.outputs)})")
        if not self._gates.admit(role, self.now_utime):
            return
        if isinstance(msg, (bytes, bytearray, memoryview)):
            self.sent[role].append(bytes(msg))  # (a reused packet buffer: copied)
        else:  # encoded and decoded, as on the bus: nothing is shared with the node
            self.sent[role].append(type(msg).decode(msg.encode()))

    def due(self, role: str) -> bool:
        return self._gates.due(role, self.now_utime)


class NodeDriver:
    """One node, its inputs put by hand, ticked by hand; see the module docstring."""

    def __init__(self, node: Node, *, limits: Mapping[str, Mapping[str, tuple[float, float]]]
                 | None = None, output_rate_hz: Mapping[str, float] | None = None,
                 setup: bool = True) -> None:
        """``limits``: the process's edge checks (hw_config ``limits``), as the runners apply
        them; every LCM input is checked finite regardless. ``setup``: call ``node.setup``."""
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
        self.ctx = DriverContext(node, output_rate_hz or {})
        self.ticks = 0
        if setup:
            node.setup(self.ctx)

    @property
    def sent(self) -> dict[str, list[Any]]:
        return self.ctx.sent

    def put(self, role: str, msg: Any) -> None:
        """``msg`` arrives on ``role`` (an LCM message is encoded on the way, as on the bus)."""
        if role not in self.ports:
            raise KeyError(f"{self.node.name} has no input {role!r} "
                           f"({', '.join(self.ports) or 'none'})")
        raw = bytes(msg) if isinstance(msg, (bytes, bytearray, memoryview)) else msg.encode()
        self.ports[role].put(raw)

    def tick(self, utime: int | None = None) -> bool:
        """One tick, as a runner makes it: a message-driven node ticks on its trigger role's
        message (the newest, or the oldest waiting with "each") and not at all when none
        came (as the runners: see ``timeout_tick``); a periodic node ticks with no trigger.
        ``utime``: the tick's sim time (default: the trigger's ``header.utime``, else the
        clock as it stands). Returns whether the node ticked."""
        role = self.node.trigger_role
        trigger = None
        if role is not None:
            port = self.ports[role]
            trigger = port.pop() if port.policy == "each" else port.take()
            if trigger is None:
                return False
        self._tick(trigger, utime)
        return True

    def timeout_tick(self, utime: int | None = None) -> None:
        """The tick a runner makes when the trigger timeout passes with nothing on the
        trigger role (``Node.trigger_timeout_s``): ``inbox.trigger()`` is None."""
        self._tick(None, utime)

    def _tick(self, trigger: Any | None, utime: int | None) -> None:
        if utime is not None:
            self.ctx.now_utime = utime
        elif trigger is not None and (header := getattr(trigger, "header", None)) is not None:
            self.ctx.now_utime = int(header.utime)
        self.inbox.set_trigger(trigger)
        self.node.tick(self.ctx, self.inbox)
        self.ticks += 1
