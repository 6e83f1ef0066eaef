"""Recording a trial's elevation maps (``cassie experiment ... --perception --record-maps``),
for the offline perception benchmark of the paper's Section VIII-D (``cassie bench
segmenters``): every map the perception node publishes, as ``cassie bench s3 --maps`` reads
them, with the mapping time of the tick that made it."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np

from runtime.codecs import elevation_map_from_msg


class MapRecorder:
    """``setup`` hook of ``run_trial``: taps the elevation-map channel and times the
    perception node's ticks; ``save`` writes the .npz."""

    def __init__(self, channel: str = "ELEVATION_MAP") -> None:
        self.channel = channel
        self.elevation: list[np.ndarray] = []
        self.lowest: list[np.ndarray] = []
        self.origin: list[tuple[float, float]] = []
        self.time_s: list[float] = []
        self.mapping_ms: list[float] = []
        self.resolution = float("nan")
        self._tick_ms = float("nan")  # wall time of the perception tick that ran last

    def __call__(self, h: Any) -> None:
        nodes = [b.node for b in h.bindings if b.node.name == "perception"]
        if not nodes:
            raise ValueError("--record-maps needs perception in the trial (--perception)")
        node = nodes[0]
        tick = node.tick

        def timed(ctx: Any, inbox: Any) -> None:
            t0 = time.perf_counter()
            tick(ctx, inbox)
            self._tick_ms = (time.perf_counter() - t0) * 1e3

        node.tick = timed
        h.tap(self.channel, self._on_map)

    def _on_map(self, _t_us: int, msg: Any) -> None:
        layers = elevation_map_from_msg(msg)
        if not isinstance(layers, dict) or msg.status != 0:
            return  # no map in it (no data yet, stale): nothing a segmenter would get
        self.resolution = float(msg.resolution)
        self.elevation.append(np.array(layers["elevation"], dtype=np.float32))
        low = layers.get("lowest")
        self.lowest.append(np.array(low if low is not None else layers["elevation"],
                                    dtype=np.float32))
        self.origin.append((float(msg.origin[0]), float(msg.origin[1])))
        self.time_s.append(msg.header.utime * 1e-6)
        self.mapping_ms.append(self._tick_ms)

    def save(self, path: Path) -> int:
        """Write the maps to ``path`` (.npz: elevation, lowest (F, R, C), origin (F, 2), time,
        mapping_ms (F,), resolution); returns the number of maps."""
        if not self.elevation:
            raise ValueError("no elevation map was published: nothing to record")
        path.parent.mkdir(parents=True, exist_ok=True)
        np.savez_compressed(path, elevation=np.stack(self.elevation),
                            lowest=np.stack(self.lowest), origin=np.array(self.origin),
                            time=np.array(self.time_s), mapping_ms=np.array(self.mapping_ms),
                            resolution=self.resolution)
        return len(self.elevation)
