"""The Node contract: an algorithm wired to named ports, with no LCM or sockets inside.

A node declares its input and output ports by role (``"state"``, ``"torque"``), how it is driven
(by each or by the newest message of one input, or periodically), and a ``tick``. The same node
object runs live (``runtime.loops``: LCM and UDP, wall clock) and inside the deterministic harness
(``runtime.harness``: sim-time order, no transport) -- the way a Drake diagram runs both ways.
Which channel a role is bound to lives in ``hw_config``, not in the node.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any, Literal, Protocol

if TYPE_CHECKING:
    import numpy as np

log = logging.getLogger(__name__)

#: A port's payload type: an lcm-gen message class, or ``bytes`` for a raw UDP datagram.
PortType = type

TriggerPolicy = Literal["newest", "each"]

#: ``Node.health``: what the supervisor makes of a process beyond its being alive
HEALTH_OK, HEALTH_WARNING, HEALTH_FAULT = 0, 1, 2


class SlotGate:
    """At most one event per slot of sim time: slot = utime // period_us.

    Used for a message-driven loop's ``max_rate_hz`` (the first trigger of each slot ticks, so
    a 1 kHz OSC on 2 kHz states ticks on every other state, and after a lost state on the next
    one) and for decimated outputs (``output_rate_hz``). Sim time, not the wall clock, so the
    harness and a live run decimate alike. Time going backwards (a sim restart) opens a slot.
    """

    __slots__ = ("_last", "period_us")

    def __init__(self, rate_hz: float) -> None:
        self.period_us = max(1, round(1e6 / rate_hz))
        self._last = -1

    def open(self, utime: int) -> bool:
        """True when ``utime`` falls in a slot that has not admitted an event yet."""
        return utime // self.period_us != self._last

    def admit(self, utime: int) -> bool:
        """``open``, and if so take the slot."""
        slot = utime // self.period_us
        if slot == self._last:
            return False
        self._last = slot
        return True


class OutputGates:
    """The ``output_rate_hz`` of a node's outputs: one ``SlotGate`` per decimated role."""

    def __init__(self, rates: Mapping[str, float]) -> None:
        self._gates = {role: SlotGate(hz) for role, hz in rates.items()}
        self.dropped = 0  # messages left out between slots

    def due(self, role: str, utime: int) -> bool:
        gate = self._gates.get(role)
        return gate is None or gate.open(utime)

    def admit(self, role: str, utime: int) -> bool:
        gate = self._gates.get(role)
        if gate is None or gate.admit(utime):
            return True
        self.dropped += 1
        return False


class TickGuard:
    """Runs a node's ``tick`` so that an exception in it never ends the process: caught,
    counted, logged (with the traceback the first times), and the node's previous outputs
    stand (its consumers keep the last good message). Both runners tick through one."""

    def __init__(self, node: Node) -> None:
        self.node = node
        self.errors = 0
        self.last_error = ""
        #: live: where the node's state is saved after each good tick (runtime.checkpoint)
        self.checkpoint: Any = None

    def tick(self, ctx: Context, inbox: Inbox) -> bool:
        """One tick; False when it raised."""
        try:
            self.node.tick(ctx, inbox)
            if self.checkpoint is not None:
                self.checkpoint.save()
            return True
        except Exception as exc:  # any bug in a tick: count it, keep running
            self.errors += 1
            self.last_error = f"{type(exc).__name__}: {exc}"[:200]
            if self.errors <= 3 or self.errors % 1000 == 0:
                log.exception("%s: tick raised (#%d), previous outputs kept", self.node.name,
                              self.errors)
            return False


class Context(Protocol):
    """What a node may do from ``setup`` and ``tick``: publish and read the sim clock."""

    def publish(self, role: str, msg: Any) -> None:
        """Send ``msg`` on the output ``role``. LCM messages get ``header.seq``,
        ``header.send_mono_ns`` and ``header.source`` filled in; the node sets ``header.utime``.
        An output with an ``output_rate_hz`` is dropped outside its slots (see ``due``)."""

    def due(self, role: str) -> bool:
        """Whether ``publish(role, ...)`` would send now (False for a decimated output between
        its slots): a node may skip building a message nobody will receive."""

    @property
    def now_utime(self) -> int:
        """Sim time (us) of this tick: the scheduled time of a periodic tick, else the
        ``header.utime`` of the driving message (0 for raw bytes)."""


class Inbox(Protocol):
    """The node's view of its inputs at a tick."""

    def latest(self, role: str) -> Any | None:
        """Newest message received on ``role`` so far (decoded), or None if none yet."""

    def is_fresh(self, role: str) -> bool:
        """True when ``role`` received something since this node's previous tick."""

    def trigger(self) -> Any | None:
        """The message that caused this tick (message-driven nodes), else None."""

    def pop(self, role: str) -> Any | None:
        """The oldest message not taken yet on an ``each`` input (``Node.input_policy``),
        else None."""

    def newest_raw(self, role: str) -> bytes | None:
        """The newest payload of ``role`` as it came off the wire if it was not decoded yet
        (unchecked: read a field or two without paying for a decode), else None."""


class Node:
    """Base class for every process's algorithm shell.

    Subclasses set the class attributes and override ``tick`` (and optionally ``setup`` and
    ``close``). ``period_s`` is filled in from the rate in ``hw_config`` for periodic nodes.
    """

    name: str = "node"
    #: role -> payload type (lcm class, or ``bytes`` for UDP); set as class attributes
    inputs: Mapping[str, PortType] = {}
    outputs: Mapping[str, PortType] = {}
    #: input role that drives the node; None means periodic at ``period_s``
    trigger_role: str | None = None
    #: "newest": tick once on the newest message, skipping stale ones (control loops);
    #: "each": tick once per message, in order (e.g. integrating every IMU packet)
    trigger_policy: TriggerPolicy = "newest"
    #: the policy of the other inputs: "newest" (the default: ``inbox.latest``) or "each"
    #: (every message, in order: ``inbox.pop``), as a target PC reads every torque packet
    input_policy: Mapping[str, TriggerPolicy] = {}
    #: with "each": the most messages kept waiting when the loop falls behind its input; older
    #: ones are dropped and counted as stale, so latency stays bounded (None: keep them all)
    max_backlog: int | None = None
    #: live, real time only: other inputs that also wake the loop, each only for its messages
    #: in the second half of every slot of the given rate in sim time (thinned in the kernel):
    #: the states a loop at that rate skips, answered by ``tick`` with no trigger (the torque
    #: bridge fills in the packets of a 1 kHz OSC's skipped states)
    off_slot_wake: Mapping[str, float] = {}
    #: live only: a receive thread keeps taking messages into the port buffers while ``tick``
    #: runs (as a camera's polling thread fills a shared frame buffer for the mapping thread);
    #: the harness ignores it (everything there is in sim-time order)
    receive_thread: bool = False
    #: inputs the node validates itself, which the runtime's edge check (``runtime.validate``)
    #: leaves alone: where a bad message calls for a reaction, not only a rejection (the
    #: torque bridge answers a NaN command with its fallback at once)
    validates_own: tuple[str, ...] = ()
    #: message-driven nodes: with no trigger for this long, a tick with ``inbox.trigger()``
    #: None (a watchdog, a resend). Live it is wall-clock seconds, read before every wait (a
    #: node may adapt it: the sim's resend timer); the harness counts it in sim time
    trigger_timeout_s: float | None = None
    #: set by the runner from ``hw_config`` (rate_hz, deadline_ms) before ``setup``
    period_s: float | None = None
    deadline_s: float | None = None

    def setup(self, ctx: Context) -> None:
        """Called once before the first tick."""

    def warm_up(self) -> None:
        """Live only, after ``setup`` and before the loop starts (and before the process is
        ready): make the first real ticks as fast as the later ones, e.g. run every compiled
        kernel once. The harness skips it: there, time is simulated and results must not
        depend on it."""

    def state_arrays(self) -> list[np.ndarray]:
        """The contiguous arrays that hold the algorithm's whole state, if it has one worth
        carrying over a crash (``runtime.checkpoint``): live, they are saved after every tick
        and a successor in the same launch loads them before its first. [] for none."""
        return []

    def restored(self) -> None:
        """Called (live) after ``state_arrays`` were loaded from a predecessor's save: the
        node decides whether that state is still good when the first input arrives."""

    def tick(self, ctx: Context, inbox: Inbox) -> None:  # pragma: no cover - abstract
        """One step of the algorithm: read ``inbox``, ``ctx.publish`` the outputs."""
        raise NotImplementedError

    def close(self) -> None:
        """Called once at shutdown; release sockets, files, threads."""

    def status(self) -> str:
        """A short human-readable status line for the supervisor and logs (sent with every
        TIMING message, about ten times a second: keep it cheap)."""
        return "ok"

    def health(self) -> int:
        """``HEALTH_OK``, ``HEALTH_WARNING`` or ``HEALTH_FAULT`` (a controller in safe mode, a
        robot that fell): a supervised ``--duration`` run fails on a fault."""
        return HEALTH_OK

    def counters(self) -> Mapping[str, float]:
        """The node's own running counts (packets, steps, published states...), sent with its
        TIMING messages so reports can check them (e.g. a state for every sim packet)."""
        return {}
