"""Scripted motions of the real MuJoCo sim, and the NUC loop around it in the harness.

Used by the estimator and bridge tests and by ``cassie bench estimator``.

A joint PD around the sim's standing pose with time-varying targets (squat, sway, alternating
leg lifts) moves the robot while the start-up pelvis holder (soft, never released) keeps it from
falling: real physics, real packets (``runtime.cassie_packets``), no balance controller needed.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from lcmtypes import robot_state_t, torque_command_t
from runtime.harness import Binding, Harness
from runtime.node import Context, Inbox, Node

KP = np.array([400.0, 400.0, 400.0, 400.0, 100.0] * 2)
KD = np.array([10.0, 10.0, 10.0, 10.0, 5.0] * 2)
MOTIONS = ("still", "squat", "steps")


def targets(motion: str, t: float, q0: np.ndarray) -> np.ndarray:
    """Motor position targets (10) at time ``t`` for a scripted ``motion``."""
    tgt = q0.copy()
    if motion == "still" or t < 0.5:
        return tgt
    s = t - 0.5
    if motion == "squat":  # knees and hips: the pelvis bobs ~5 cm, sways sideways
        a = math.sin(2 * math.pi * 0.7 * s)
        tgt[[3, 8]] += 0.25 * a
        tgt[[2, 7]] -= 0.12 * a
        tgt[[0, 5]] += 0.08 * math.sin(2 * math.pi * 0.5 * s)
    elif motion == "steps":  # alternate smooth leg lifts: single and double stance, touchdowns
        for leg, phase in ((0, 0.0), (1, math.pi)):
            lift = max(0.0, math.sin(2 * math.pi * 0.5 * s + phase)) ** 2
            tgt[5 * leg + 3] -= 0.6 * lift
            tgt[5 * leg + 2] += 0.4 * lift
    else:
        raise ValueError(f"unknown motion {motion!r}, one of {MOTIONS}")
    return tgt


def pd_torque(motion: str, t: float, q0: np.ndarray, pos: np.ndarray, vel: np.ndarray
              ) -> np.ndarray:
    """Joint-side torques of the scripted PD."""
    return KP * (targets(motion, t, q0) - pos) - KD * vel


class ScriptedController(Node):
    """Stands in for the OSC: scripted joint PD on the estimated state's motor joints."""

    name = "scripted"
    inputs = {"state": robot_state_t}
    outputs = {"torque": torque_command_t}
    trigger_role = "state"
    trigger_policy = "newest"

    def __init__(self, motion: str, q0_motors: np.ndarray, motor_qpos: np.ndarray,
                 motor_dof: np.ndarray) -> None:
        self.motion = motion
        self.q0 = q0_motors
        self.qi = motor_qpos
        self.vi = motor_dof
        self.stop_after_us: int | None = None  # go silent (the bridge's watchdog trips)
        self.nan_at_us: int | None = None  # publish one NaN command at this time
        self._cmd = torque_command_t()
        self._cmd.num_motors = 10

    def tick(self, ctx: Context, inbox: Inbox) -> None:
        s = inbox.trigger()
        if s is None:
            return
        t_us = int(s.header.utime)
        if self.stop_after_us is not None and t_us > self.stop_after_us:
            return
        q = np.asarray(s.q)
        v = np.asarray(s.v)
        tau = pd_torque(self.motion, t_us * 1e-6, self.q0, q[self.qi], v[self.vi])
        if self.nan_at_us is not None and self.nan_at_us <= t_us < self.nan_at_us + 500:
            tau[2] = float("nan")
        c = self._cmd
        c.header.utime = t_us
        c.torque = tau.tolist()
        ctx.publish("torque", c)


@dataclass
class LoopRecord:
    """What a harness run recorded, by sim utime."""

    truth: dict[int, Any] = field(default_factory=dict)
    states: dict[int, Any] = field(default_factory=dict)
    network: list[int] = field(default_factory=list)
    packets: list[bytes] = field(default_factory=list)  # raw robot-output datagrams
    contacts: list[Any] = field(default_factory=list)
    applied: list[Any] = field(default_factory=list)
    sim: Any = None
    estimator: Any = None
    controller: Any = None
    bridge: Any = None
    harness: Any = None


def sim_settings(holder_timeconst_s: float = 0.2) -> Any:
    """Sim settings for tests: flat ground, no camera, a soft pelvis holder never released."""
    from sim.process import SimSettings
    from sim.target_pc import HolderConfig, SimConfig

    return SimSettings(
        sim=SimConfig(holder=HolderConfig(release_on="manual", timeconst_s=holder_timeconst_s)),
        camera_enabled=False,
    )  # ground truth at every step: the harness bindings below set no output_rate_hz


def run_loop(motion: str, seconds: float, *, stop_after_s: float | None = None,
             nan_at_s: float | None = None, bridge_params: Any = None,
             estimator_params: Any = None,
             progress: Callable[[int], None] | None = None) -> LoopRecord:
    """Sim -> estimator -> scripted PD -> torque bridge -> sim, in the deterministic harness
    (``progress(sim_us)``: the harness's progress callback, for a caller's progress bar)."""
    from processes.state_estimator.process import StateEstimatorNode
    from processes.torque_bridge.process import TorqueBridgeNode
    from sim.process import SimNode

    sim = SimNode(sim_settings(), "realtime")
    core = sim.core
    est = StateEstimatorNode(estimator_params)
    ctrl = ScriptedController(motion, core.q_start[core.idx.motor_qpos].copy(),
                              core.idx.motor_qpos, core.idx.motor_dof)
    if stop_after_s is not None:
        ctrl.stop_after_us = round(stop_after_s * 1e6)
    if nan_at_s is not None:
        ctrl.nan_at_us = round(nan_at_s * 1e6)
    bridge = TorqueBridgeNode(bridge_params)
    h = Harness([
        Binding(sim, inputs={"command": "ROBOT_INPUT"},
                outputs={"robot_output": "ROBOT_OUTPUT", "ground_truth": "GROUND_TRUTH",
                         "depth": "DEPTH"}),
        Binding(est, inputs={"robot_output": "ROBOT_OUTPUT"},
                outputs={"state": "CASSIE_STATE", "network_state": "NETWORK_CASSIE_STATE",
                         "contact": "CASSIE_CONTACT"}),
        Binding(ctrl, inputs={"state": "CASSIE_STATE"}, outputs={"torque": "OSC_TORQUE"}),
        Binding(bridge, inputs={"torque": "OSC_TORQUE", "state": "CASSIE_STATE"},
                outputs={"robot_input": "ROBOT_INPUT", "applied_input": "CASSIE_INPUT"}),
    ])
    rec = LoopRecord(sim=sim, estimator=est, controller=ctrl, bridge=bridge, harness=h)
    h.tap("GROUND_TRUTH", lambda t, m: rec.truth.__setitem__(int(m.header.utime), m))
    h.tap("CASSIE_STATE", lambda t, m: rec.states.__setitem__(int(m.header.utime), m))
    h.tap("ROBOT_OUTPUT", lambda t, raw: rec.packets.append(bytes(raw)))
    h.tap("NETWORK_CASSIE_STATE", lambda t, m: rec.network.append(int(m.header.utime)))
    h.tap("CASSIE_CONTACT", lambda t, m: rec.contacts.append(m))
    h.tap("CASSIE_INPUT", lambda t, m: rec.applied.append(m))
    h.run_until(round(seconds * 1e6), progress=progress)
    h.close()
    return rec


def errors(rec: LoopRecord, skip_s: float = 0.0) -> dict[str, np.ndarray]:
    """Estimate minus truth at every utime both have: pelvis position, velocity, contact."""
    keys = sorted(k for k in rec.states if k in rec.truth and k >= skip_s * 1e6)
    est_q = np.array([rec.states[k].q[0:3] for k in keys])
    est_v = np.array([rec.states[k].v[0:3] for k in keys])
    tru_q = np.array([rec.truth[k].q[0:3] for k in keys])
    tru_v = np.array([rec.truth[k].v[0:3] for k in keys])
    return {
        "t": np.array(keys) * 1e-6,
        "pos": est_q - tru_q,
        "vel": est_v - tru_v,
        "true_pos": tru_q,
        "true_vel": tru_v,
        "est_contact": np.array([rec.states[k].in_contact for k in keys]),
        "true_contact": np.array([rec.truth[k].foot_contact for k in keys]),
    }

