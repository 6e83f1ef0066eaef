"""The torque bridge process: newest torque command in, one UDP torque packet per robot state.

Inputs ``torque`` (torque_command_t, newest) and ``state`` (robot_state_t, the trigger, newest):
like the robot's 2 kHz cycle, each state answers with one packet, whose ``ack`` is the ``seq``
of the target-PC packet the state came from (``processes.state_estimator.process``), so the
target PC can count round trips and run in lockstep. Outputs ``robot_input`` (bytes, UDP) and
``applied_input`` (applied_input_t: torques sent, as commanded, source and counters), stamped
with the state's ``utime``.
"""

from __future__ import annotations

import functools
import logging

import mujoco
import numpy as np

from lcmtypes import applied_input_t, robot_state_t, torque_command_t
from processes.state_estimator.process import packet_seq_of
from runtime.cassie_packets import (
    FLAG_RELEASE_HOLDER,
    MOTOR_NAMES,
    NUM_MOTORS,
    InputPacket,
    LinkCounter,
)
from runtime.config import process_gains
from runtime.config_types import ProcessConfig, Profile
from runtime.node import Context, Inbox, Node

from .bridge import DEFAULT_GAINS_FILE, SOURCE_COMMAND, BridgeParams, TorqueBridge

log = logging.getLogger(__name__)


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

    def __init__(self, params: BridgeParams | None = None) -> None:
        self.params = params or BridgeParams()
        self.bridge = TorqueBridge(self.params)
        self.link = LinkCounter()
        self.pkt = InputPacket()
        self._dofs: np.ndarray | None = None
        self._mv = np.zeros(NUM_MOTORS)
        self._msg = applied_input_t()
        self._msg.num_motors = NUM_MOTORS

    def setup(self, ctx: Context) -> None:
        self._dofs = motor_dofs()

    def tick(self, ctx: Context, inbox: Inbox) -> None:
        state = inbox.trigger() or inbox.latest("state")
        if state is None:
            return
        b = self.bridge
        if inbox.is_fresh("torque"):
            cmd = inbox.latest("torque")
            if cmd is not None:
                b.on_command(cmd.torque, cmd.header.utime)
        v = state.v
        if self._dofs is not None and len(v) > int(self._dofs.max()):
            self._mv[:] = [v[i] for i in self._dofs]
        else:
            self._mv[:] = np.nan  # malformed state: the damping fallback degrades to zero
        utime = int(state.header.utime)
        trips, rejects = b.watchdog_trips, b.nan_rejects
        tau = b.step(utime, self._mv)
        if b.watchdog_trips != trips:
            log.warning("torque bridge watchdog tripped (#%d) at t=%.4f s: %s", b.watchdog_trips,
                        utime * 1e-6, b.status())
        if b.nan_rejects != rejects and (b.nan_rejects <= 10 or b.nan_rejects % 1000 == 0):
            log.warning("torque command rejected (#%d): %s", b.nan_rejects, b.last_reason)
        pkt = self.pkt
        pkt.torque[:] = tau
        release = self.params.release_holder and b.source == SOURCE_COMMAND
        pkt.flags = FLAG_RELEASE_HOLDER if release else 0
        ctx.publish("robot_input", pkt.to_bytes(self.link.next_seq(), packet_seq_of(state)))
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


def make_node(proc: ProcessConfig, profile: Profile) -> Node:
    """Build the bridge: settings from ``proc.gains_file`` (relative to hw_config), else
    ``hw_config/gains/torque_bridge.yaml``; no free-form ``params`` are accepted."""
    path = process_gains(proc, DEFAULT_GAINS_FILE)
    node = TorqueBridgeNode(BridgeParams.from_yaml(path))
    node.name = proc.name
    return node
