"""The sim node runs inside the runtime's deterministic harness (periodic in sim time, a
controller answering each state packet) and two runs give identical ground truth."""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from runtime.builder import build_node
from runtime.cassie_packets import InputPacket, LinkCounter, OutputPacket
from runtime.harness import Binding, Harness
from runtime.node import Context, Inbox, Node

from .conftest import make_proc, make_profile


class JointPd(Node):
    """A stand-in NUC: PD on the motors towards the first state's positions, over packets."""

    name = "pd"
    inputs: ClassVar[dict[str, type]] = {"robot_output": bytes}
    outputs: ClassVar[dict[str, type]] = {"command": bytes}
    trigger_role = "robot_output"

    def __init__(self) -> None:
        self.state, self.cmd, self.link = OutputPacket(), InputPacket(), LinkCounter()
        self.q0: np.ndarray | None = None

    def tick(self, ctx: Context, inbox: Inbox) -> None:
        self.state.decode(inbox.trigger())
        self.link.on_receive(self.state.seq, self.state.ack)
        if self.q0 is None:
            self.q0 = self.state.motor_pos.copy()
        self.cmd.torque[:] = 200.0 * (self.q0 - self.state.motor_pos) - 5.0 * self.state.motor_vel
        ctx.publish("command", self.cmd.to_bytes(self.link.next_seq(), self.link.last_peer_seq))


def _run() -> list[Any]:
    proc = make_proc({"terrain": "stairs", "drive": "periodic"})
    sim = build_node(proc, make_profile("lockstep"))
    assert sim.trigger_role is None and sim.render_mode == "inline"  # deterministic frames
    h = Harness([
        Binding(sim, inputs={"command": "ROBOT_INPUT"},
                outputs={"robot_output": "ROBOT_OUTPUT", "ground_truth": "GROUND_TRUTH",
                         "depth": "DEPTH"}, output_rate_hz={"ground_truth": 500.0}),
        Binding(JointPd(), inputs={"robot_output": "ROBOT_OUTPUT"},
                outputs={"command": "ROBOT_INPUT"}, delay_us=300),
    ])
    truth: list[Any] = []
    depth: list[int] = []
    h.tap("GROUND_TRUTH", lambda t, m: truth.append((t, m.q, m.foot_contact)))
    h.tap("DEPTH", lambda t, m: depth.append(hash(bytes(m.data))))
    h.run_until(60_000)
    assert sim.tpc.link.received > 100 and not sim.core.holder_engaged
    h.close()
    return [truth, depth, sim.core.d.qpos.tobytes()]


def test_two_harness_runs_give_identical_ground_truth() -> None:
    a = _run()
    b = _run()
    assert len(a[0]) == 31 and len(a[1]) == 2  # 500 Hz ground truth, 30 Hz depth, 0..60 ms
    assert a == b
