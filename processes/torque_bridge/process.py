"""The torque bridge process: torque commands in, UDP torque packets to the target PC out.

Inputs ``torque`` (torque_command_t) and ``state`` (robot_state_t); outputs ``robot_input``
(bytes, UDP) and ``applied_input`` (applied_input_t: torques sent, as commanded, source and
counters), stamped with the state's ``utime``. Each packet's ``ack`` is the ``seq`` of the
target-PC packet of the newest state (``processes.state_estimator.process``), so the target PC
counts round trips and can run in lockstep. What sends a packet (``params.answer_on``):

* ``command`` (real time): each torque command, at once, as SYSTEM.md's bridge ("driven by
  each torque command, plus a watchdog"): the torque computed from a state reaches the target
  PC in the same 0.5 ms cycle when the chain keeps up. When commands stop, a watchdog tick
  every ``WATCHDOG_TICK_S`` of wall time answers the newest state with the fallback once no
  fresh command is left (the watchdog counts in state sim time, as always). With
  ``params.fill_hz`` (the OSC's ``max_rate_hz``) the bridge is also woken by each state in
  the second half of every slot of that rate -- the states a rate-limited OSC skips, passed
  by the kernel (``Node.off_slot_wake``) -- and answers it with the newest torque, so the
  target PC still gets a packet every 0.5 ms cycle from a 1 kHz OSC.
* ``state``: each robot state, with the newest command.
* ``torque`` (lockstep): each torque answers the state it was computed from, sending the
  torque of the state before (the robot's one-tick latency, made exact).
"""

from __future__ import annotations

import functools
import logging
from dataclasses import dataclass

import mujoco
import numpy as np

from lcmtypes import applied_input_t, robot_state_t, torque_command_t
from runtime.cassie_packets import (
    FLAG_RELEASE_HOLDER,
    MOTOR_NAMES,
    NUM_MOTORS,
    InputPacket,
    LinkCounter,
)
from runtime.codecs import packet_seq_of, raw_utime_and_seq
from runtime.config_types import ProcessConfig, Profile
from runtime.node import Context, Inbox, Node
from runtime.pairing import link_token
from runtime.params import spec

from .bridge import SOURCE_COMMAND, BridgeGains, BridgeParams, TorqueBridge

log = logging.getLogger(__name__)

#: answer_on command: with no command for this long (wall), tick anyway to run the watchdog
WATCHDOG_TICK_S = 0.002
#: a fill answers a state read undecoded only this far (us of sim time) past the last answer
FILL_MAX_AHEAD_US = 50_000
#: ... and one such state in this long (us of sim time) is decoded and checked all the same
FILL_CHECK_EVERY_US = 100_000


@functools.cache
def _default_motor_dofs() -> tuple[int, ...]:
    from processes.state_estimator.kinematics import load_model

    return tuple(int(i) for i in motor_dofs(load_model()))


def motor_dofs(model: mujoco.MjModel | None = None) -> np.ndarray:
    """Indices of the 10 motors' velocities in the model's ``v`` (MOTOR_NAMES order)."""
    if model is None:
        return np.array(_default_motor_dofs(), dtype=np.intp)
    ids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, n) for n in MOTOR_NAMES]
    return model.jnt_dofadr[ids].astype(np.intp)


class TorqueBridgeNode(Node):
    """Torque command (LCM) -> clamped, watchdogged torque packet (UDP) per robot state."""

    name = "torque_bridge"
    inputs = {"torque": torque_command_t, "state": robot_state_t}
    outputs = {"robot_input": bytes, "applied_input": applied_input_t}
    trigger_role = "state"
    trigger_policy = "newest"
    #: a NaN or over-limit command gets the fallback at once (TorqueBridge.on_command), not
    #: the previous torques until the watchdog: the bridge checks commands itself
    validates_own = ("torque",)

    def __init__(self, params: BridgeParams | None = None, answer_on: str = "state",
                 fill_hz: float | None = None) -> None:
        self.params = params or BridgeParams()
        self.answer_on = answer_on
        self.trigger_timeout_s: float | None = None
        if answer_on == "command":
            self.trigger_role = "torque"
            self.trigger_timeout_s = WATCHDOG_TICK_S
            self._answered_utime = -1
            self._checked_utime = -FILL_CHECK_EVERY_US  # the newest state decoded on a fill
            if fill_hz:
                self.off_slot_wake = {"state": float(fill_hz)}
        if answer_on == "torque":
            # lockstep: answer a state once the controller has run on it, so the target PC
            # steps only after the whole chain (estimator -> OSC -> here) has seen its state;
            # the torque sent is the one computed from the state before (the robot's one-tick
            # latency, made exact), so lockstep runs behave as the 2 kHz cycle does
            self.trigger_role = "torque"
        self.unmatched = 0  # lockstep: torques that did not answer the newest state
        self.fills = 0  # answer_on command: states answered with the held torque
        self.fills_skipped = 0  # ... and states already overtaken by a later command
        self._lazy: Inbox | None = None  # where the fallback may read the newest state
        self._pending: tuple[list[float], int] | None = None
        self.bridge = TorqueBridge(self.params)
        self.link = LinkCounter()
        self.pkt = InputPacket(link_token())  # the sim takes torques only with this token
        self._dofs: list[int] = []
        self._dof_max = -1
        self._mv = np.zeros(NUM_MOTORS)
        self._state: robot_state_t | None = None  # the state being answered
        self._flags = -1  # the flags the packet holds
        self._release_holder = self.params.release_holder
        #: set the release flag once the controller has stood or walked this long (sim time,
        #: us): the robot stands in the holder before it is let go (params.release_after_s)
        self.release_after_us: int | None = None
        self._controlled_since = -1
        self._msg = applied_input_t()
        self._msg.num_motors = NUM_MOTORS

    def setup(self, ctx: Context) -> None:
        self._dofs = [int(i) for i in motor_dofs()]
        self._dof_max = max(self._dofs)

    def tick(self, ctx: Context, inbox: Inbox) -> None:
        b = self.bridge
        if self.answer_on == "command":
            cmd = inbox.trigger()
            if cmd is not None:
                # the command carries its state's utime and packet seq (the ack): no state is
                # decoded per command; the newest one is read only if the fallback needs its
                # motor velocities (a rejected command)
                cmd_utime = int(cmd.header.utime)
                b.on_command(cmd.torque, cmd_utime)
                self._note_mode(cmd)
                self._answered_utime = max(self._answered_utime, cmd_utime)
                self._lazy = inbox
                self._send(ctx, b, cmd_utime, None, int(cmd.state_packet_seq) & 0xFF)
                self._lazy = None
                return
            # a state to fill in (``fill_hz``), or a watchdog tick (no command for
            # WATCHDOG_TICK_S): answer a newer state, if any. A fill needs only the state's
            # utime and packet seq (the torque is the newest command's): read from its bytes,
            # not decoded (a third of a fill's CPU, measured), when they follow on from what
            # was answered; anything else, and the fallback's velocities, decodes and checks
            head = self._fill_header(inbox)
            state = None
            if head is not None and head[0] - self._checked_utime >= FILL_CHECK_EVERY_US:
                # states read undecoded pass no edge check, whose clock (utime_step_s) then
                # falls behind: measured, after a bridge's take-over a second of fills, then a
                # decoded state rejected as 1.5 s off its clock, the fallback, and a fall
                head = None
            if head is None:
                state = inbox.latest("state")
                if state is not None:
                    self._checked_utime = int(state.header.utime)
                    head = self._checked_utime, packet_seq_of(state)
            if head is None or head[0] <= self._answered_utime:
                self.fills_skipped += 1  # a command for a later state went out first
                return
            self.fills += 1
            self._answered_utime = head[0]
            self._lazy = inbox
            self._send(ctx, b, head[0], state, head[1])
            self._lazy = None
            return
        if self.trigger_role == "torque":
            cmd = inbox.trigger()
            state = inbox.latest("state")
            if cmd is None or state is None or cmd.header.utime != state.header.utime:
                self.unmatched += 1  # an older state's torque: the newest one's is coming
                return
            if self._pending is not None:
                b.on_command(*self._pending)
            self._pending = (list(cmd.torque), int(cmd.header.utime))
            self._note_mode(cmd)
        else:
            state = inbox.trigger() or inbox.latest("state")
            if state is None:
                return
            if inbox.is_fresh("torque"):
                cmd = inbox.latest("torque")
                if cmd is not None:
                    b.on_command(cmd.torque, cmd.header.utime)
                    self._note_mode(cmd)
        self._send(ctx, b, int(state.header.utime), state, packet_seq_of(state))

    def _fill_header(self, inbox: Inbox) -> tuple[int, int] | None:
        """(utime, ack) of the newest state, undecoded, if it is a state this bridge may fill
        in on sight: newer than the last answered one by at most ``FILL_MAX_AHEAD_US`` (a
        corrupt utime far off is decoded and checked at the edge instead)."""
        raw = inbox.newest_raw("state")
        head = raw_utime_and_seq(raw) if raw is not None else None
        if head is None or not 0 < head[0] - self._answered_utime <= FILL_MAX_AHEAD_US:
            return None
        return head

    def _note_mode(self, cmd: torque_command_t) -> None:
        """``release_after_s``: release once the controller has stood or walked (mode 0 or 1)
        without a break for that long; safe mode or off starts the count again."""
        after = self.release_after_us
        if after is None or self._release_holder:
            return
        utime = int(cmd.header.utime)
        if int(cmd.mode) not in (0, 1):
            self._controlled_since = -1
        elif self._controlled_since < 0:
            self._controlled_since = utime
        elif utime - self._controlled_since >= after:
            self._release_holder = True
            log.info("controller standing for %.1f s: releasing the start-up holder at t=%.4f s",
                     after * 1e-6, utime * 1e-6)

    def _motor_velocities(self) -> np.ndarray:
        """The motor velocities of the state being answered (for the damping fallback only:
        read when the bridge falls back, not per command); NaN without a well-formed state,
        which makes the fallback zero torque."""
        if self._state is None and self._lazy is not None:
            self._state = self._lazy.latest("state")
        v = self._state.v if self._state is not None else ()
        if self._dofs and len(v) > self._dof_max:
            self._mv[:] = [v[i] for i in self._dofs]
        else:
            self._mv[:] = np.nan
        return self._mv

    def _send(self, ctx: Context, b: TorqueBridge, utime: int, state: robot_state_t | None,
              ack: int) -> None:
        """The torques for the robot at ``utime`` (watchdog, clamps), as one packet."""
        self._state = state
        trips, rejects = b.watchdog_trips, b.nan_rejects
        pkt = self.pkt
        tau = b.step(utime, self._motor_velocities, out=pkt.torque)  # into the packet too
        if b.watchdog_trips != trips:
            log.warning("torque bridge watchdog tripped (#%d) at t=%.4f s: %s", b.watchdog_trips,
                        utime * 1e-6, b.status())
        if b.nan_rejects != rejects and (b.nan_rejects <= 10 or b.nan_rejects % 1000 == 0):
            log.warning("torque command rejected (#%d): %s", b.nan_rejects, b.last_reason)
        release = self._release_holder and b.source == SOURCE_COMMAND
        flags = FLAG_RELEASE_HOLDER if release else 0
        if flags != self._flags:
            pkt.flags = self._flags = flags
        pkt.encode(self.link.next_seq(), ack)
        # the packet's own buffer: the live runner sends it at once, the harness copies it
        ctx.publish("robot_input", pkt.buffer)
        if not ctx.due("applied_input"):  # decimated (processes.torque_bridge.output_rate_hz)
            return
        m = self._msg
        m.header.utime = utime
        m.torque = tau.tolist()
        m.commanded = b.commanded.tolist()
        m.source = b.source
        m.command_age_ms = b.age_ms if np.isfinite(b.age_ms) else -1.0
        m.watchdog_trips = b.watchdog_trips
        m.clamp_count = b.clamp_count
        m.nan_rejects = b.nan_rejects
        m.status = b.status()
        ctx.publish("applied_input", m)

    def status(self) -> str:
        return self.bridge.status()

    def counters(self) -> dict[str, float]:
        """Torque packets sent, and why the watchdog or the checks stepped in."""
        b = self.bridge
        return {
            "packets_sent": self.link.sent,
            "watchdog_trips": b.watchdog_trips,
            "clamps": b.clamp_count,
            "nan_rejects": b.nan_rejects,
            "unmatched": self.unmatched,
            "fills": self.fills,
            "fills_skipped": self.fills_skipped,
        }


@dataclass(frozen=True)
class Params:
    """The bridge's ``params:`` (processes.yaml, a profile's ``overrides:``)."""

    #: what sends a packet: ``state`` (each robot state is answered with the newest torque, as
    #: on the robot), ``command`` (each torque command at once, plus the watchdog's ticks),
    #: ``torque`` (each torque answers the state it was computed from: the sim's lockstep
    #: waits for the controller) or ``auto`` (torque in lockstep profiles, command otherwise)
    answer_on: str = spec("auto", choices=("auto", "command", "state", "torque"))
    #: answer_on command: also answer the states a rate-limited OSC skips, at this rate (the
    #: OSC's max_rate_hz), with the newest torque; None: not
    fill_hz: float | None = spec(None, lo=0.0, hi=2000.0, lo_open=True, unit="Hz")
    #: seconds of the controller standing before the holder is released (with the sim's
    #: params.holder_release: manual); None: the gains file's release_holder alone
    release_after_s: float | None = spec(None, lo=0.0, hi=60.0, unit="s")


#: the gains file (``gains:``, hw_config/gains/torque_bridge.yaml)
Gains = BridgeGains


def make_node(proc: ProcessConfig, profile: Profile, params: Params,
              gains: BridgeGains) -> Node:
    """The bridge of ``gains`` and ``params`` (``runtime.builder.build_node`` reads and checks
    both); ``answer_on: auto`` is ``torque`` in a lockstep profile, ``command`` otherwise."""
    answer = params.answer_on
    if answer == "auto":
        answer = "torque" if profile.mode == "lockstep" else "command"
    node = TorqueBridgeNode(BridgeParams.from_gains(gains), answer, params.fill_hz)
    node.name = proc.name
    if params.release_after_s is not None:
        node.release_after_us = round(params.release_after_s * 1e6)
    return node
