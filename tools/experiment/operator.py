"""The operator of a trial: the radio's velocity command, steering the robot back onto the
course's centre line (Section VIII-A): heading 0 along the x axis, or on a winding course
(``Terrain.path``) the heading towards a point ``LOOKAHEAD_M`` ahead on its centre line."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from lcmtypes import command_t, ground_truth_t
from runtime.node import Node
from tools.experiment.judge import HEADING_GAIN

#: the operator's lateral speed per metre off the centre line (1/s), and its bound
LATERAL_GAIN = 0.0
LATERAL_MAX_MPS = 0.2
#: how far ahead on a winding course's centre line the operator aims (m): about 2.5 s of
#: walking at 0.375 m/s, so the turn into a 1 m segment begins before the joint rather than
#: after it. Measured on the 35 cm winding beam with ground truth (seed 0): at 0.4 m (a second,
#: the heading loop's time constant 1 / HEADING_GAIN) the robot came off a 26 deg segment
#: still turned 20 deg left, walked to the next one's edge and fell at 6.2 s; at 0.7 m fell at
#: 11.4 s; at 1.0 m crossed, and so on seeds 1-5
LOOKAHEAD_M = 1.0
#: the radio's yaw-rate range (rad/s), as the processes' command inputs bound it
#: (hw_config/processes.yaml): a command outside is rejected at the edge, not clipped there
YAW_RATE_MAX = 1.5


class Operator(Node):
    """The operator's radio in the harness: the commanded speed, and a yaw rate proportional
    to the heading error (as the paper's simulation experiments command the OSC)."""

    name = "operator"
    inputs = {"ground_truth": ground_truth_t}
    outputs = {"command": command_t}

    def __init__(self, vx: float, lateral_gain: float = LATERAL_GAIN,
                 stand: bool = False,
                 path: Sequence[tuple[float, float]] | np.ndarray = ()) -> None:
        self.vx = vx
        self.lateral_gain = lateral_gain
        self.stand = stand  # the radio's stand switch (command_t.mode 1)
        self.period_s = 0.05  # 20 Hz, as a radio sends
        #: the course's centre line (``Terrain.path``); None: the x axis
        self.path = np.asarray(path, dtype=float).reshape(-1, 2) if len(path) >= 2 else None

    def command(self, utime: int, gt: Any | None) -> command_t:
        """The radio's message: walk at ``vx``, turning back to heading 0."""
        cmd = command_t()
        cmd.header.utime = utime
        cmd.vx = 0.0 if self.stand else self.vx
        cmd.mode = 1 if self.stand else 0
        if gt is not None:
            w, x, y, z = gt.q[3:7]
            yaw = float(np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z)))
            if self.path is None:
                cmd.yaw_rate = float(np.clip(-HEADING_GAIN * yaw, -YAW_RATE_MAX, YAW_RATE_MAX))
                # and sideways back onto the course's centre line y = 0 (the command is in
                # the pelvis-yaw frame: the world's lateral speed, turned into it)
                vy_world = float(np.clip(-self.lateral_gain * float(gt.q[1]),
                                         -LATERAL_MAX_MPS, LATERAL_MAX_MPS))
                cmd.vy = float(np.cos(yaw) * vy_world)
                return cmd
            heading, off, normal = follow(self.path, float(gt.q[0]), float(gt.q[1]))
            turn = HEADING_GAIN * math.remainder(heading - yaw, 2.0 * math.pi)
            cmd.yaw_rate = float(np.clip(turn, -YAW_RATE_MAX, YAW_RATE_MAX))
            v = float(np.clip(-self.lateral_gain * off, -LATERAL_MAX_MPS, LATERAL_MAX_MPS))
            # the world's lateral speed along the line's left normal, in the pelvis-yaw frame
            cmd.vy = float(v * (np.cos(yaw) * normal[1] - np.sin(yaw) * normal[0]))
        return cmd

    def tick(self, ctx: Any, inbox: Any) -> None:
        ctx.publish("command", self.command(ctx.now_utime, inbox.latest("ground_truth")))


def follow(path: np.ndarray, x: float, y: float,
           lookahead: float = LOOKAHEAD_M) -> tuple[float, float, np.ndarray]:
    """Where the operator steers on a course's centre line (a polyline): the heading (rad)
    from (x, y) to the point ``lookahead`` metres on from the line's point nearest (x, y)
    (pure pursuit; the last piece runs on past the end), the signed distance off the line
    (m, left positive) and that piece's left normal."""
    a, b = path[:-1], path[1:]
    d = b - a
    length = np.hypot(d[:, 0], d[:, 1])
    t = ((x - a[:, 0]) * d[:, 0] + (y - a[:, 1]) * d[:, 1]) / length ** 2
    t[:-1] = np.minimum(t[:-1], 1.0)
    t = np.maximum(t, 0.0)
    near = a + t[:, None] * d
    k = int(np.argmin(np.hypot(near[:, 0] - x, near[:, 1] - y)))
    u = d[k] / length[k]
    normal = np.array((-u[1], u[0]))
    off = float((x - near[k, 0]) * normal[0] + (y - near[k, 1]) * normal[1])
    # the arc length of the nearest point, then the point lookahead further on
    ends = np.cumsum(length)
    s = float(ends[k] - length[k] + t[k] * length[k]) + lookahead
    j = min(int(np.searchsorted(ends, s)), len(length) - 1)
    target = a[j] + (s - (ends[j] - length[j])) / length[j] * d[j]
    return float(np.arctan2(target[1] - y, target[0] - x)), off, normal


