"""Driving the torque bridge node in the deterministic harness with states and commands."""

from __future__ import annotations

from typing import Any

import numpy as np

from lcmtypes import robot_state_t, torque_command_t
from processes.torque_bridge.bridge import BridgeParams
from processes.torque_bridge.process import TorqueBridgeNode
from runtime.cassie_packets import InputPacket
from runtime.harness import Binding, Harness

NQ, NV = 35, 32
MOTOR_DOFS = [6, 7, 8, 12, 18, 19, 20, 21, 25, 31]  # checked against the model in a test


def state(utime: int, motor_vel: float = 0.0, seq: int = 0) -> robot_state_t:
    s = robot_state_t()
    s.header.utime = utime
    s.num_positions, s.num_velocities, s.num_motors = NQ, NV, 10
    s.q = [0.0] * NQ
    v = [0.0] * NV
    for i in MOTOR_DOFS:
        v[i] = motor_vel
    s.v = v
    s.motor_torque = [0.0] * 10
    s.packet_seq = seq & 0xFF
    return s


def command(utime: int, torque: Any, seq: int | None = None) -> torque_command_t:
    """A torque command computed from the state at ``utime`` (whose packet seq is ``seq``,
    by default the 2 kHz count utime / 500 us, as ``state`` numbers them in these tests)."""
    c = torque_command_t()
    c.header.utime = utime
    c.state_packet_seq = (utime // 500 if seq is None else seq) & 0xFF
    t = [float(x) for x in torque]
    c.num_motors = len(t)
    c.torque = t
    return c


class BridgeRig:
    """The bridge node bound in a harness; every sent packet and applied_input is recorded."""

    def __init__(self, params: BridgeParams | None = None) -> None:
        self.node = TorqueBridgeNode(params)
        self.h = Harness([Binding(self.node, inputs={"torque": "CMD", "state": "STATE"},
                                  outputs={"robot_input": "UDP", "applied_input": "APPLIED"})])
        self.packets: list[InputPacket] = []
        self.applied: list[Any] = []

        def on_packet(_t: int, raw: bytes) -> None:
            p = InputPacket()
            p.decode(raw)
            self.packets.append(p)

        self.h.tap("UDP", on_packet)
        self.h.tap("APPLIED", lambda _t, m: self.applied.append(m))

    def cycle(self, utime: int, cmd: Any | None = None, motor_vel: float = 0.0) -> Any:
        """At ``utime``: optionally a command, then a state (which triggers one send)."""
        if cmd is not None:
            self.h.inject("CMD", command(utime, cmd), at_us=utime)
        self.h.inject("STATE", state(utime, motor_vel, seq=utime // 500), at_us=utime)
        self.h.run_until(utime)
        return self.applied[-1]

    @property
    def torque(self) -> np.ndarray:
        return self.packets[-1].torque.copy()


def packets(driver: Any) -> list[InputPacket]:
    """The torque packets a ``runtime.driver.NodeDriver`` of the bridge sent, decoded."""
    out = []
    for raw in driver.sent["robot_input"]:
        p = InputPacket()
        p.decode(raw)
        out.append(p)
    return out
