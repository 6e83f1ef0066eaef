"""The sim's terrain as static boxes, so the 3D view shows what the robot walks on.

The terrain is taken from the launch profile's sim process (``params.terrain``), or from
``--terrain NAME|FILE``. This is optional: any failure is logged once and the dashboard goes on.
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Any

import numpy as np
import rerun as rr

from runtime.config_types import Profile

log = logging.getLogger(__name__)


def find_terrain(profile: Profile | None, spec: str | None) -> Any | None:
    """A ``sim.terrain.Terrain`` from ``spec`` (generator name or YAML path) or the profile."""
    try:
        from sim import terrain as terrain_mod

        if spec:
            if spec in terrain_mod.GENERATORS:
                return terrain_mod.generate(spec)
            path = Path(spec)
            if not path.exists() and profile is not None:
                path = profile.resolve(spec)
            return terrain_mod.load_terrain(path)
        if profile is None:
            return None
        from sim.process import resolve_terrain

        for name in profile.launch:
            proc = profile.processes[name]
            if proc.module.startswith("sim"):
                return resolve_terrain(proc, profile)
    except Exception as exc:  # optional: never stop the dashboard for it
        log.warning("no terrain shown (%s)", exc)
    return None


def log_terrain(rec: rr.RecordingStream, terrain: Any) -> int:
    """Log the terrain's boxes (static) under ``world/terrain``; returns how many."""
    boxes = list(getattr(terrain, "boxes", ()))
    if not boxes:
        return 0
    centers = np.array([b.center for b in boxes], np.float64)
    half = 0.5 * np.array([b.size for b in boxes], np.float64)
    quats = np.array([[*b.quat_wxyz[1:], b.quat_wxyz[0]] for b in boxes], np.float64)  # xyzw
    rec.log(
        "world/terrain",
        rr.Boxes3D(
            centers=centers,
            half_sizes=half,
            quaternions=quats,
            colors=[(150, 140, 125)],
            fill_mode="solid",
        ),
        static=True,
    )
    return len(boxes)
