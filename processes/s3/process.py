"""The S3 process: each elevation map -> convex foothold polygons (Section VI).

Driven by the newest elevation map; runs Stable Steppability Segmentation and the convex
decomposition, and publishes the foothold set with the map's ``utime`` (so the latency from the
depth frame to the footholds can be read from a log) and the map's sequence number. A bad map
(empty, all NaN, stale, malformed) yields an empty or the previous set with a status that says
why; nothing here raises on data.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from lcmtypes import elevation_map_t, foothold_set_t, foothold_t
from processes.s3.params import S3Params
from processes.s3.pipeline import S3Pipeline, S3Result
from runtime.config_types import ProcessConfig, Profile
from runtime.node import Node

STATUS_OK, STATUS_PREVIOUS, STATUS_EMPTY = 0, 1, 2


def decode_layers(msg: elevation_map_t) -> dict[str, np.ndarray] | str:
    """The map's float32 layers by name, or a string saying why they cannot be read."""
    cells = msg.rows * msg.cols
    if msg.rows <= 0 or msg.cols <= 0:
        return f"empty map ({msg.rows} x {msg.cols})"
    if msg.num_layers != len(msg.layer_names) or len(msg.data) != 4 * cells * msg.num_layers:
        return (
            f"malformed map: {msg.num_layers} layers of {msg.rows} x {msg.cols} but "
            f"{len(msg.data)} bytes"
        )
    flat = np.frombuffer(msg.data, dtype="<f4")
    return {
        name: flat[i * cells : (i + 1) * cells].reshape(msg.rows, msg.cols)
        for i, name in enumerate(msg.layer_names)
    }


def foothold_message(result: S3Result, utime: int, map_seq: int) -> foothold_set_t:
    """S3 result -> foothold_set_t (planes + half-spaces + vertices, world frame)."""
    out = foothold_set_t()
    out.header.utime = utime
    out.map_seq = map_seq
    for f in result.footholds:
        m = foothold_t()
        m.normal = [float(x) for x in f.normal]
        m.offset = float(f.offset)
        m.num_halfspaces = len(f.b)
        m.A = np.asarray(f.A, dtype=float).tolist()
        m.b = np.asarray(f.b, dtype=float).tolist()
        verts = f.vertices
        m.num_vertices = len(verts)
        m.vertices = np.asarray(verts, dtype=float).tolist()
        out.footholds.append(m)
    out.num_footholds = len(out.footholds)
    if result.status == "stale map":
        out.status = STATUS_PREVIOUS
    else:
        out.status = STATUS_OK if out.num_footholds else STATUS_EMPTY
    out.status_text = result.status
    return out


class S3Node(Node):
    """Elevation map in, foothold set out."""

    name = "s3"
    inputs = {"elevation_map": elevation_map_t}
    outputs = {"footholds": foothold_set_t}
    trigger_role = "elevation_map"

    def __init__(self, params: S3Params) -> None:
        self.pipeline = S3Pipeline(params)
        self.last_status = "no map yet"
        self.maps = 0

    def tick(self, ctx: Any, inbox: Any) -> None:
        msg: elevation_map_t = inbox.trigger()
        self.maps += 1
        layers = decode_layers(msg)
        if isinstance(layers, str) or "elevation" not in layers:
            why = layers if isinstance(layers, str) else "map has no 'elevation' layer"
            result = self.pipeline.process(np.empty((0, 0)), msg.resolution or 1.0, np.zeros(2))
            result.status = f"bad input: {why}"
        else:
            # A map whose time does not advance is stale: the pipeline keeps the previous set.
            map_time = msg.header.utime * 1e-6
            result = self.pipeline.process(
                layers["elevation"],
                msg.resolution,
                np.asarray(msg.origin, dtype=float),
                map_time_s=map_time,
                now_s=ctx.now_utime * 1e-6,
                lowest=layers.get("lowest"),
            )
        self.last_status = result.status
        ctx.publish("footholds", foothold_message(result, msg.header.utime, msg.header.seq))

    def status(self) -> str:
        return f"{self.maps} maps; last: {self.last_status}"


#: the gains file (hw_config/gains/s3.yaml): Table VIII, in the variant ``Params.variant`` names
Gains = S3Params


@dataclass(frozen=True)
class Params:
    """S3's ``params:`` (hw_config/processes.yaml, and the profiles' overrides)."""

    variant: str = "simulation"  # the column of Table VIII: a variant of the gains file


def make_node(proc: ProcessConfig, profile: Profile, params: Params, gains: S3Params) -> Node:
    """S3 from hw_config (gains: Table VIII, per variant)."""
    return S3Node(gains)
