"""The operator of a trial: the radio's velocity command, steering the robot back onto the
course's centre line (Section VIII-A)."""

from __future__ import annotations

from typing import Any

import numpy as np

from lcmtypes import command_t, ground_truth_t
from runtime.node import Node
from tools.experiment.judge import HEADING_GAIN

#: the operator's lateral speed per metre off the centre line (1/s), and its bound
LATERAL_GAIN = 0.0
LATERAL_MAX_MPS = 0.2


class Operator(Node):
    """The operator's radio in the harness: the commanded speed, and a yaw rate proportional
    to the heading error (as the paper's simulation experiments command the OSC)."""

    name = "operator"
    inputs = {"ground_truth": ground_truth_t}
    outputs = {"command": command_t}

    def __init__(self, vx: float, lateral_gain: float = LATERAL_GAIN,
                 stand: bool = False) -> None:
        self.vx = vx
        self.lateral_gain = lateral_gain
        self.stand = stand  # the radio's stand switch (command_t.mode 1)
        self.period_s = 0.05  # 20 Hz, as a radio sends

    def command(self, utime: int, gt: Any | None) -> command_t:
        """The radio's message: walk at ``vx``, turning back to heading 0."""
        cmd = command_t()
        cmd.header.utime = utime
        cmd.vx = 0.0 if self.stand else self.vx
        cmd.mode = 1 if self.stand else 0
        if gt is not None:
            w, x, y, z = gt.q[3:7]
            yaw = float(np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z)))
            cmd.yaw_rate = -HEADING_GAIN * yaw
            # and sideways back onto the course's centre line y = 0 (the command is in the
            # pelvis-yaw frame: the world's lateral speed, turned into it)
            vy_world = float(np.clip(-self.lateral_gain * float(gt.q[1]),
                                     -LATERAL_MAX_MPS, LATERAL_MAX_MPS))
            cmd.vy = float(np.cos(yaw) * vy_world)
        return cmd

    def tick(self, ctx: Any, inbox: Any) -> None:
        ctx.publish("command", self.command(ctx.now_utime, inbox.latest("ground_truth")))


