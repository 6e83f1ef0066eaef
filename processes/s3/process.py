"""The S3 process: each elevation map -> convex foothold polygons (Section VI).

Driven by the newest elevation map; runs Stable Steppability Segmentation and the convex
decomposition, and publishes the foothold set with the map's ``utime`` (so the latency from the
depth frame to the footholds can be read from a log) and the map's sequence number. A bad map
(empty, all NaN, stale, malformed) yields an empty or the previous set with a status that says
why; nothing here raises on data. With ``params.method`` ``contours`` (the DCM planner's front
end) or ``superpixels`` (QuadPiPS' superpixel planar regions) that extraction runs in S3's
place, on the same channels.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from lcmtypes import elevation_map_t, foothold_set_t
from processes.dcm_planner.regions import ContourRegions, RegionParams
from processes.s3.params import S3Params
from processes.s3.pipeline import STATUS_STALE, S3Pipeline, S3Result
from processes.superpixels import SuperpixelParams, SuperpixelSegmenter
from runtime.codecs import elevation_map_from_msg, footholds_to_msg
from runtime.config_types import ProcessConfig, Profile
from runtime.geometry import Foothold
from runtime.node import Node
from runtime.params import load, spec


def foothold_message(result: S3Result, utime: int, map_seq: int) -> foothold_set_t:
    """S3 result -> foothold set (planes + half-spaces + corners, world frame); a stale map's
    set says the previous footholds were kept."""
    return footholds_to_msg(result.footholds, utime, map_seq, result.status,
                            previous=result.status == STATUS_STALE)


class Regions(Protocol):
    """A foothold extraction run in S3's place: one map in, its footholds out."""

    def process(self, elevation: np.ndarray, resolution: float, origin_xy: np.ndarray,
                map_time_s: float) -> list[Foothold]: ...


class S3Node(Node):
    """Elevation map in, foothold set out."""

    name = "s3"
    inputs = {"elevation_map": elevation_map_t}
    outputs = {"footholds": foothold_set_t}
    trigger_role = "elevation_map"

    def __init__(self, params: S3Params, regions: Regions | None = None,
                 method: str = "contours") -> None:
        self.pipeline = S3Pipeline(params)
        #: the DCM planner's front end or the superpixels in S3's place (params.method)
        self.regions = regions
        self.method = method
        self.last_status = "no map yet"
        self.maps = 0

    def tick(self, ctx: Any, inbox: Any) -> None:
        msg: elevation_map_t = inbox.trigger()
        self.maps += 1
        layers = elevation_map_from_msg(msg)
        if self.regions is not None and not isinstance(layers, str) and "elevation" in layers:
            held = self.regions.process(layers["elevation"], msg.resolution,
                                        np.asarray(msg.origin, dtype=float),
                                        msg.header.utime * 1e-6)
            self.last_status = f"ok: {len(held)} {self.method} regions"
            ctx.publish("footholds", footholds_to_msg(
                held, msg.header.utime, msg.header.seq, "ok" if held else "no safe terrain"))
            return
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
    #: the foothold extraction: s3 (S3 + convex decomposition, Section VI), contours (the
    #: DCM planner's front end, Xiang et al. Alg. 3: processes.dcm_planner.regions) or
    #: superpixels (QuadPiPS' superpixel planar regions: processes.superpixels)
    method: str = spec("s3", choices=("s3", "contours", "superpixels"))
    #: the contour front end's gains file, relative to the profile's hw_config folder (or absolute)
    regions_gains: str = "gains/dcm_regions.yaml"
    #: the superpixels' gains file, relative to the profile's hw_config folder (or absolute)
    superpixels_gains: str = "gains/superpixels.yaml"


def make_node(proc: ProcessConfig, profile: Profile, params: Params, gains: S3Params) -> Node:
    """S3 from hw_config (gains: Table VIII, per variant), or the contour front end, or the
    superpixels."""
    regions: Regions | None = None
    if params.method == "contours":
        regions = ContourRegions(load(RegionParams, profile.resolve(params.regions_gains)))
    elif params.method == "superpixels":
        regions = SuperpixelSegmenter(load(SuperpixelParams,
                                           profile.resolve(params.superpixels_gains)))
    return S3Node(gains, regions, params.method)
