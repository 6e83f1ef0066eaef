"""The state estimator process: a ``Node`` around ``CassieEstimator``.

Input ``robot_output`` (bytes: the target PC's UDP packet; the trigger, policy ``each`` so every
packet is integrated in order). Outputs, all stamped with the packet's sim ``utime``:
``state`` (robot_state_t, one per valid packet, CASSIE_STATE), ``network_state`` (the same
message every ``network_every``-th valid packet: 200 Hz for the laptop, NETWORK_CASSIE_STATE;
the ALIP fields, the MPFC's input, are computed on those packets only, so the 2 kHz path stays
within its 0.5 ms period)
and ``contact`` (contact_t, one per valid packet).

With ``params.truth_state`` (simulation only: the paper's runs with ground-truth state, Section
VIII-A) the published pose and velocity are the simulator's own (input ``ground_truth``, the
sim's GROUND_TRUTH of the same packet's ``utime``) instead of the filter's; contact, the ALIP
filter and every counter stay the estimator's, and the filter runs as always. A robot process
knows no simulator: the truth comes over the bus, as the ground-truth footholds do.

A datagram that fails ``runtime.cassie_packets`` validation (size, version, kind, NaN/inf) or
the estimator's range checks is rejected: counted in ``packets_rejected``, logged (rate-limited)
and never passed on. Sequence gaps are counted by ``LinkCounter`` into ``packets_lost``.

``robot_state_t.packet_seq`` carries the packet's 8-bit ``seq``: the torque bridge sends it back
as its ``ack``, which the target PC's lockstep mode waits for; ``target_status`` carries the
target PC's status bits and ``status`` the estimator's own ``STATUS_*`` flags.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from lcmtypes import contact_t, ground_truth_t, robot_state_t
from runtime.cassie_packets import (
    OUTPUT_SIZE,
    UTIME_AT,
    LinkCounter,
    OutputPacket,
    PacketError,
)
from runtime.config_types import ProcessConfig, Profile
from runtime.errors import ConfigError
from runtime.node import Context, Inbox, Node

from .estimator import STATUS_PACKET_GAP, CassieEstimator, RejectedPacket
from .kernels import OK
from .params import EstimatorParams

#: a saved state (``state_arrays``) is carried on from when the first packet comes at most
#: this long after it (us of sim time); older, the estimator starts afresh
MAX_CARRY_OVER_US = 50_000

log = logging.getLogger(__name__)


class StateEstimatorNode(Node):
    """UDP robot output in; robot state (2 kHz and 200 Hz) and contact out."""

    name = "state_estimator"
    inputs = {"robot_output": bytes}  # and ground_truth with ``truth_state`` (__init__)
    outputs = {"state": robot_state_t, "network_state": robot_state_t, "contact": contact_t}
    trigger_role = "robot_output"
    trigger_policy = "each"
    max_backlog = 400  # 200 ms of packets: a stall shorter than that loses none (they are
    # integrated late, in order: lost packets would make the estimate drift); beyond it the
    # oldest are dropped and counted, so the lag stays bounded

    def __init__(self, params: EstimatorParams | None = None, fused: bool = True,
                 truth_state: bool = False) -> None:
        self.params = params or EstimatorParams()
        #: publish the sim's true pose and velocity (module docstring)
        self.truth_state = truth_state
        self.truth_stale = 0  # states published with a truth older than their packet
        if truth_state:
            self.inputs = {**type(self).inputs, "ground_truth": ground_truth_t}
        self.fused = fused  # False: the modular Python estimator (the fused step's reference)
        self._network_every = self.params.network_every
        self._last_seq = -1
        self._nq = self._nqv = 0
        self.estimator: CassieEstimator | None = None
        self.link = LinkCounter()
        self.pkt = OutputPacket()
        self.rejected = 0
        self.estimator_resets = 0
        #: the datagram the newest published state was estimated from, seq ``_last_seq``
        #: (a copy: garbage or a rejected packet in between must not make its lockstep
        #: resend look new)
        self._last_good = bytearray(OUTPUT_SIZE)
        self._restored = False
        self._loss_logs = 0
        self.published = 0
        self.last_error = ""
        self._state = robot_state_t()
        self._contact = contact_t()

    def setup(self, ctx: Context) -> None:
        self.estimator = CassieEstimator(self.params, fused=self.fused)
        m = self.estimator.kin.m
        s = self._state
        s.num_positions, s.num_velocities, s.num_motors = int(m.nq), int(m.nv), 10
        self._nq, self._nqv = int(m.nq), int(m.nq + m.nv)

    def state_arrays(self) -> list[np.ndarray]:
        """The fused estimator's whole state (InEKF, contact, ALIP filter: two packed arrays),
        carried over a crash: a successor that started afresh put the walking robot back
        at the origin with zero velocity and no contact, and it fell (measured)."""
        est = self.estimator
        return [] if est is None or not est.fused else [est._S, est._N]

    def restored(self) -> None:
        self._restored = True  # judged on the first packet (tick): is it still that robot?

    def _reject(self, reason: str) -> None:
        self.rejected += 1
        self.last_error = reason
        if self.rejected <= 10 or self.rejected % 1000 == 0:
            log.warning("rejected robot-output packet #%d: %s", self.rejected, reason)

    def tick(self, ctx: Context, inbox: Inbox) -> None:
        data = inbox.trigger()
        if data is None:
            return
        est = self.estimator
        assert est is not None
        pkt, link = self.pkt, self.link
        if data[0] == self._last_seq and data == self._last_good:
            # the same datagram again (lockstep resends a state whose answer was lost), even
            # with garbage between the two (measured: a zero-filled datagram in between made
            # the resend "stale", rejected, resent for ever, and the lockstep loop stalled):
            # count it and answer it again, so the torque bridge re-sends its command
            link.on_receive(data[0], data[1])
            ctx.publish("state", self._state)
            return
        if self._restored and len(data) == OUTPUT_SIZE:
            self._restored = False
            utime = int.from_bytes(bytes(data[UTIME_AT:UTIME_AT + 8]), "little", signed=True)
            gap_us = utime - est._last_utime
            if not 0 < gap_us <= MAX_CARRY_OVER_US:
                est.initialized = False  # too old (or another run's): start afresh
                log.info("the saved state is %.1f ms from the first packet: starting afresh",
                         gap_us / 1e3)
            else:
                log.info("carrying on from a state %.1f ms before the first packet",
                         gap_us / 1e3)
        to_laptop = self.published % self._network_every == 0
        failed = ""
        try:
            # decode + range checks + estimate: one compiled call (CassieEstimator.step)
            code = est.step(data, pkt, alip=to_laptop)
        except (PacketError, RejectedPacket) as exc:
            link.on_error()
            self._reject(str(exc))
            return
        except (np.linalg.LinAlgError, FloatingPointError, ValueError) as exc:
            code, failed = -1, f"estimator failed: {exc}"
        lost_before = link.lost
        link.on_receive(data[0], data[1])
        if link.lost != lost_before and (self._loss_logs < 10
                                         or link.lost // 1000 > lost_before // 1000):
            self._loss_logs += 1
            log.warning("lost %d robot-output packet(s) before seq %d (%d lost so far)",
                        link.lost - lost_before, data[0], link.lost)
        if code != OK:
            # never pass a broken estimate on: drop it and start again from the next packet
            self.estimator_resets += 1
            est.initialized = False
            if failed:
                self.last_error = failed
            self._reject(failed or "estimate became non-finite")
            return
        self._last_good[:] = data  # (an accepted datagram is OUTPUT_SIZE long: no allocation)
        self._last_seq = data[0]
        utime, status, stance, c0, c1, alip_changed, target_status = est.out_ints.tolist()
        ctx.now_utime = utime  # a raw packet drove this tick: its utime is the sim time
        s = self._state
        s.header.utime = utime
        f = est.out_floats.tolist()  # q, v, motor torques, IMU specific force
        nq, nv = self._nq, self._nqv
        s.q, s.v, s.motor_torque, s.imu_accel = f[:nq], f[nq:nv], f[nv:-3], f[-3:]
        if self.truth_state:
            self._take_truth(inbox, s, utime)
        if alip_changed:  # the ALIP fields change only on the laptop's packets (and a reset)
            s.alip_stance = stance
            s.alip_x = est.est.alip_x.tolist()
            s.alip_stance_pos = est.est.stance_pos.tolist()
        s.in_contact = [c0 != 0, c1 != 0]
        s.status = status | STATUS_PACKET_GAP if link.lost > lost_before else status
        s.target_status = target_status
        s.packet_seq = data[0]
        s.packets_lost = link.lost
        s.packets_rejected = self.rejected
        ctx.publish("state", s)
        if to_laptop:
            ctx.publish("network_state", s)
        self.published += 1
        if not ctx.due("contact"):  # decimated (processes.state_estimator.output_rate_hz)
            return
        c = self._contact
        c.header.utime = utime
        c.in_contact = [c0 != 0, c1 != 0]
        c.spring_deflection = est.est.spring_defl.tolist()
        c.force_estimate = est.est.force.tolist()
        ctx.publish("contact", c)

    def _take_truth(self, inbox: Inbox, s: robot_state_t, utime: int) -> None:
        """The sim's true q and v into ``s`` (``truth_state``): the newest GROUND_TRUTH, counted
        in ``truth_stale`` when it is not of this packet's utime."""
        gt = inbox.latest("ground_truth")
        if gt is None or len(gt.q) != self._nq or len(gt.v) != self._nqv - self._nq:
            self.truth_stale += 1
            return
        if gt.header.utime != utime:
            self.truth_stale += 1
        s.q, s.v = list(gt.q), list(gt.v)

    def counters(self) -> dict[str, float]:
        """Packets in, states out: a report checks a state for every packet of the sim."""
        out = {
            "packets_received": self.link.received,
            "packets_lost": self.link.lost,
            "packets_rejected": self.rejected,
            "states_published": self.published,
            "estimator_resets": self.estimator_resets,
        }
        if self.truth_state:
            out["truth_stale"] = self.truth_stale
        return out

    def status(self) -> str:
        s = f"published {self.published} rejected {self.rejected} {self.link.summary()}"
        if self.last_error:
            s += f" last error: {self.last_error}"
        return s


@dataclass(frozen=True)
class Params:
    """The estimator's ``params:``; every setting of the filter lives in its gains file."""

    #: publish the simulator's true pose and velocity (input ``ground_truth`` bound to the
    #: sim's GROUND_TRUTH at every step): the paper's ground-truth-state runs, sim only
    truth_state: bool = False


#: the gains file (``gains:``, hw_config/gains/state_estimator.yaml), section by section
Gains = EstimatorParams


def make_node(proc: ProcessConfig, profile: Profile, params: Params,
              gains: EstimatorParams) -> Node:
    """The estimator of ``gains`` (``runtime.builder.build_node`` reads and checks both)."""
    if params.truth_state and "ground_truth" not in proc.inputs:
        raise ConfigError(str(proc.source_file), f"processes.{proc.name}.params.truth_state",
                          "true, but the process has no ground_truth input",
                          allowed="false, or inputs: {ground_truth: ground_truth} with the "
                                  "sim's output_rate_hz.ground_truth at its step rate")
    node = StateEstimatorNode(gains, truth_state=params.truth_state)
    node.name = proc.name
    return node
