"""Moving obstacles against S3's hysteresis (the paper's Section VIII-D-4, Table IV): foam
cubes dropped in front of the robot, standing or walking, with perception in the loop; a cube
is *segmented out* when it makes a hole in S3's safe terrain before it comes to rest.

One trial per hysteresis value ``k_hyst``: the experiment profile on flat ground with the
depth camera, elevation map and S3 (its gains file with that ``k_hyst``), the sim dropping
``--cubes`` cubes (``sim.target_pc.DropsConfig``) a second or two apart. Judged from the
sim's cube poses and S3's own safe mask per map (in the harness, so the same command gives the
same table on any machine): a cube's footprint (its inner square) must be all safe in the last
S3 frame before its drop (else it is "not seen": the camera did not cover that ground), and it
counts as segmented out when some cell of it is unsafe in any S3 frame from the drop until it
is at rest (speed below ``REST_MPS`` for ``REST_S``).
"""

from __future__ import annotations

import math
import tempfile
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from runtime.config import HW_CONFIG_DIR, load_profile, safe_load
from runtime.harness import Binding, Harness
from tools.experiment.courses import _write_profile
from tools.experiment.operator import Operator

REST_MPS = 0.02  # a cube slower than this ...
REST_S = 0.1  # ... for this long is at rest
HYSTERESIS = (0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6)  # Table IV's columns


@dataclass
class CubeVerdict:
    """One dropped cube: where and when, when it came to rest, and what S3 made of it."""

    dropped_s: float
    x_m: float
    y_m: float
    rest_s: float = -1.0  # -1: still moving when the trial ended
    seen: bool = False  # its footprint was safe ground in S3's frame before the drop
    segmented: bool = False  # a hole in S3's safe terrain under it before it came to rest
    hole_s: float = -1.0  # the first such S3 frame's map time


@dataclass
class CubesTrial:
    k_hyst: float
    standing: bool
    obstacle_variance_m2: float | None = None
    cubes: list[CubeVerdict] = field(default_factory=list)
    fell: bool = False
    s3_frames: int = 0

    @property
    def segmented(self) -> int:
        return sum(c.segmented for c in self.cubes)


def _gains_with(name: str, key: str, value: float, work: Path) -> Path:
    """hw_config/gains/NAME.yaml with ``key`` set to ``value`` at the top and in every
    variant that sets it."""
    src = HW_CONFIG_DIR / "gains" / f"{name}.yaml"
    doc = safe_load(src.read_text())
    doc[key] = float(value)
    for v in (doc.get("variants") or {}).values():
        if isinstance(v, dict) and key in v:
            v[key] = float(value)
    path = work / f"{name}_{key}.yaml"
    path.write_text(f"# {src} with {key} = {value}\n" + yaml.safe_dump(doc, sort_keys=False))
    return path


def _profile(base: Path, k_hyst: float, drops: dict[str, Any], work: Path,
             obstacle_variance: float | None = None) -> Path:
    """The experiment profile on flat ground with perception, the drops, S3's k_hyst and
    (not None) the elevation map's obstacle_variance_m2."""
    prof, _ = _write_profile(base, "cubes", str(HW_CONFIG_DIR / "terrains" / "flat.yaml"),
                             True, work)
    doc = safe_load(prof.read_text())
    doc["overrides"]["sim"]["params"]["drops"] = drops
    doc["overrides"]["s3"] = {"gains": str(_gains_with("s3", "k_hyst", k_hyst, work))}
    if obstacle_variance is not None:
        doc["overrides"]["perception"] = {"gains": str(_gains_with(
            "elevation_map", "obstacle_variance_m2", obstacle_variance, work))}
    prof.write_text(yaml.safe_dump(doc, sort_keys=False))
    return prof


def footprint_unsafe(mask: np.ndarray, origin: np.ndarray, resolution: float, x: float,
                     y: float, half: float) -> tuple[bool, bool]:
    """(any cell of the square footprint unsafe, the footprint inside the map) for the cells
    whose centres lie within ``half`` of (x, y) on the safe ``mask``."""
    rows, cols = mask.shape
    j0 = math.ceil((x - half - origin[0]) / resolution)
    j1 = math.floor((x + half - origin[0]) / resolution)
    i0 = math.ceil((y - half - origin[1]) / resolution)
    i1 = math.floor((y + half - origin[1]) / resolution)
    if j0 < 0 or i0 < 0 or j1 >= cols or i1 >= rows or j1 < j0 or i1 < i0:
        return False, False
    return bool((mask[i0:i1 + 1, j0:j1 + 1] == 0).any()), True


def run_cubes_trial(k_hyst: float, standing: bool, cubes: int = 3, first_s: float = 3.0,
                    every_s: float = 2.0, base: Path = HW_CONFIG_DIR / "experiment.yaml",
                    vx: float = 0.375, obstacle_variance: float | None = None) -> CubesTrial:
    """One trial at ``k_hyst``: ``cubes`` cubes dropped ``every_s`` apart from ``first_s``
    after the release, 0.9 m ahead of the pelvis (on its line, then 0.5 m to either side:
    a cube's hole, with the safety margin, stays clear of the next one's ground);
    ``obstacle_variance``: the elevation map's ``obstacle_variance_m2`` (None: its gains
    file's)."""
    drops = {"after_release_s": [first_s + i * every_s for i in range(cubes)],
             "side_m": [0.0, 0.5, -0.5], "ahead_m": 0.9,
             "height_m": 0.6, "size_m": 0.15, "seed": 0}
    out = CubesTrial(k_hyst, standing, obstacle_variance)
    with tempfile.TemporaryDirectory() as tmp:
        profile = load_profile(_profile(base, k_hyst, drops, Path(tmp), obstacle_variance))
        h = Harness.from_profile(profile)
        nodes = {b.node.name: b.node for b in h.bindings}
        op = Operator(vx, stand=standing)
        h.add(Binding(op, inputs={"ground_truth": profile.channels["ground_truth"].name},
                      outputs={"command": profile.channels["command"].name}))
        core = nodes["sim"].core
        frames: list[tuple[float, np.ndarray, np.ndarray, float]] = []  # t, mask, origin, res
        pipe = nodes["s3"].pipeline
        process = pipe.process

        def recorded(elevation: Any, resolution: float, origin: Any, **kw: Any) -> Any:
            r = process(elevation, resolution, origin, **kw)
            if r.safe_mask.size:
                frames.append((core.time, r.safe_mask.copy(), np.asarray(origin, float),
                               float(resolution)))
            return r

        pipe.process = recorded
        still_since: list[float | None] = [None] * cubes
        rest: list[float] = [-1.0] * cubes
        #: per cube, where it was (t, x, y) from its drop until it came to rest
        track: list[list[tuple[float, float, float]]] = [[] for _ in range(cubes)]

        def watch(_t: int, _gt: Any) -> None:
            for i, (pos, speed) in enumerate(core.cube_states()):
                if rest[i] >= 0:
                    continue
                track[i].append((core.time, float(pos[0]), float(pos[1])))
                if speed < REST_MPS:
                    still_since[i] = still_since[i] if still_since[i] is not None else core.time
                    if core.time - still_since[i] >= REST_S:
                        rest[i] = still_since[i]
                else:
                    still_since[i] = None

        h.tap(profile.channels["ground_truth"].name, watch)
        end_us = round((first_s + cubes * every_s + 1.0) * 1e6)
        h.run_until(end_us)
        out.fell = nodes["sim"].health() != 0
        out.s3_frames = len(frames)
        half = 0.5 * drops["size_m"] - 0.01  # the inner square: a margin for the turn
        for i, (t_drop, _, _) in enumerate(core.drops_done):
            path = track[i] or [(t_drop, *core.cube_states()[i][0][:2])]
            _, x_rest, y_rest = path[-1]  # where it came to rest (or was at the end)
            v = CubeVerdict(t_drop, x_rest, y_rest, rest[i])
            before = [f for f in frames if f[0] < t_drop]
            if before:  # the ground it lands on (where it falls: x, y of its drop)
                _, m, o, res = before[-1]
                unsafe, inside = footprint_unsafe(m, o, res, path[0][1], path[0][2], half)
                v.seen = inside and not unsafe
            end = rest[i] if rest[i] >= 0 else math.inf
            for t, m, o, res in frames:
                if not t_drop <= t <= end:
                    continue
                # where the cube was when that map was made
                _, x, y = min(path, key=lambda p: abs(p[0] - t))
                if footprint_unsafe(m, o, res, x, y, half)[0]:
                    v.segmented, v.hole_s = True, t
                    break
            out.cubes.append(v)
        h.close()
    return out


def trial_record(tr: CubesTrial) -> dict[str, Any]:
    """A JSON-able record of a trial."""
    return {"k_hyst": tr.k_hyst, "standing": tr.standing, "fell": tr.fell,
            "obstacle_variance_m2": tr.obstacle_variance_m2,
            "s3_frames": tr.s3_frames, "segmented": tr.segmented,
            "cubes": [asdict(c) for c in tr.cubes]}
