"""The state estimator process: a ``Node`` around ``CassieEstimator``.

Input ``robot_output`` (bytes: the target PC's UDP packet; the trigger, policy ``each`` so every
packet is integrated in order). Outputs, all stamped with the packet's sim ``utime``:
``state`` (robot_state_t, one per valid packet, CASSIE_STATE), ``network_state`` (the same
message every ``network_every``-th valid packet: 200 Hz for the laptop, NETWORK_CASSIE_STATE;
the ALIP fields, the MPFC's input, are computed on those packets only, so the 2 kHz path stays
within its 0.5 ms period)
and ``contact`` (contact_t, one per valid packet).

A datagram that fails ``runtime.cassie_packets`` validation (size, version, kind, NaN/inf) or
the estimator's range checks is rejected: counted in ``packets_rejected``, logged (rate-limited)
and never passed on. Sequence gaps are counted by ``LinkCounter`` into ``packets_lost``.

``robot_state_t.packet_seq`` carries the packet's 8-bit ``seq``: the torque bridge sends it back
as its ``ack``, which the target PC's lockstep mode waits for; ``target_status`` carries the
target PC's status bits and ``status`` the estimator's own ``STATUS_*`` flags.
"""

from __future__ import annotations

import logging

import numpy as np

from lcmtypes import contact_t, robot_state_t
from runtime.cassie_packets import LinkCounter, OutputPacket, PacketError
from runtime.config import process_gains
from runtime.config_types import ProcessConfig, Profile
from runtime.node import Context, Inbox, Node

from .estimator import CassieEstimator, RejectedPacket
from .params import DEFAULT_GAINS_FILE, EstimatorParams

log = logging.getLogger(__name__)


def packet_seq_of(state: robot_state_t) -> int:
    """The target PC packet ``seq`` a state was estimated from (for the torque's ``ack``)."""
    return int(state.packet_seq) & 0xFF


class StateEstimatorNode(Node):
    """UDP robot output in; robot state (2 kHz and 200 Hz) and contact out."""

    name = "state_estimator"
    inputs = {"robot_output": bytes}
    outputs = {"state": robot_state_t, "network_state": robot_state_t, "contact": contact_t}
    trigger_role = "robot_output"
    trigger_policy = "each"
    max_backlog = 40  # 20 ms of packets: beyond that, skip (and count) the oldest: bounded lag

    def __init__(self, params: EstimatorParams | None = None) -> None:
        self.params = params or EstimatorParams()
        self.estimator: CassieEstimator | None = None
        self.link = LinkCounter()
        self.pkt = OutputPacket()
        self.rejected = 0
        self.estimator_resets = 0
        self._last_ok = False
        self._loss_logs = 0
        self.published = 0
        self.last_error = ""
        self._state = robot_state_t()
        self._contact = contact_t()

    def setup(self, ctx: Context) -> None:
        self.estimator = CassieEstimator(self.params)
        m = self.estimator.kin.m
        s = self._state
        s.num_positions, s.num_velocities, s.num_motors = int(m.nq), int(m.nv), 10

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
        pkt = self.pkt
        if (self._last_ok and len(data) == len(pkt.buffer) and data[0] == pkt.seq
                and bytes(data) == bytes(pkt.buffer)):
            # the same datagram again (lockstep resends a state whose answer was lost):
            # count it and answer it again, so the torque bridge re-sends its command
            self.link.on_receive(pkt.seq, pkt.ack)
            ctx.publish("state", self._state)
            return
        self._last_ok = False
        try:
            pkt.decode(data)  # validates size, version, kind, finiteness
            est.check(pkt)  # physically plausible ranges, utime advancing
        except (PacketError, RejectedPacket) as exc:
            self.link.on_error()
            self._reject(str(exc))
            return
        lost_before = self.link.lost
        self.link.on_receive(pkt.seq, pkt.ack)
        if self.link.lost != lost_before and (self._loss_logs < 10
                                              or self.link.lost // 1000 > lost_before // 1000):
            self._loss_logs += 1
            log.warning("lost %d robot-output packet(s) before seq %d (%d lost so far)",
                        self.link.lost - lost_before, pkt.seq, self.link.lost)
        try:
            to_laptop = self.published % self.params.network_every == 0
            e = est.update(pkt, gap=self.link.lost > lost_before, alip=to_laptop)
            ok = bool(np.isfinite(e.q).all() and np.isfinite(e.v).all()
                      and np.isfinite(e.alip_x).all())
        except (np.linalg.LinAlgError, FloatingPointError, ValueError) as exc:
            ok, e = False, None
            self.last_error = f"estimator failed: {exc}"
        if not ok:
            # never pass a broken estimate on: drop it and start again from the next packet
            self.estimator_resets += 1
            est.initialized = False
            self._reject(self.last_error if e is None else "estimate became non-finite")
            return
        self._last_ok = True  # pkt.buffer now holds the packet this state was estimated from
        ctx.now_utime = e.utime  # a raw packet drove this tick: its utime is the sim time
        s = self._state
        s.header.utime = e.utime
        s.q = e.q.tolist()
        s.v = e.v.tolist()
        s.motor_torque = pkt.motor_torque.tolist()
        s.imu_accel = pkt.imu_accel.tolist()
        s.alip_stance = e.alip_stance
        s.alip_x = e.alip_x.tolist()
        s.alip_stance_pos = e.stance_pos.tolist()
        s.in_contact = list(e.in_contact)
        s.status = int(e.status)
        s.target_status = int(pkt.status)
        s.packet_seq = int(pkt.seq)
        s.packets_lost = self.link.lost
        s.packets_rejected = self.rejected
        ctx.publish("state", s)
        if to_laptop:
            ctx.publish("network_state", s)
        self.published += 1
        if not ctx.due("contact"):  # decimated (processes.state_estimator.output_rate_hz)
            return
        c = self._contact
        c.header.utime = e.utime
        c.in_contact = list(e.in_contact)
        c.spring_deflection = e.spring_defl.tolist()
        c.force_estimate = e.force.tolist()
        ctx.publish("contact", c)

    def counters(self) -> dict[str, float]:
        """Packets in, states out: a report checks a state for every packet of the sim."""
        return {
            "packets_received": self.link.received,
            "packets_lost": self.link.lost,
            "packets_rejected": self.rejected,
            "states_published": self.published,
            "estimator_resets": self.estimator_resets,
        }

    def status(self) -> str:
        s = f"published {self.published} rejected {self.rejected} {self.link.summary()}"
        if self.last_error:
            s += f" last error: {self.last_error}"
        return s


def make_node(proc: ProcessConfig, profile: Profile) -> Node:
    """Build the estimator: gains from ``proc.gains_file`` (relative to hw_config), else
    ``hw_config/gains/state_estimator.yaml``; no free-form ``params`` are accepted."""
    path = process_gains(proc, DEFAULT_GAINS_FILE)
    node = StateEstimatorNode(EstimatorParams.from_yaml(path))
    node.name = proc.name
    return node
