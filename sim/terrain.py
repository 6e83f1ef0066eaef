"""Terrains for the sim: boxes on a ground plane (or over a pit), plus ground-truth footholds.

A ``Terrain`` is plain data: the boxes ``sim.model`` adds as MuJoCo geoms, and the convex
foothold polygons (each box's top face shrunk by a margin) a controller can use when it runs
with perfect terrain knowledge. A terrain file may also give the foot's size
(``foot_half_size``): the footholds then shrink by it too, so that a foot centred anywhere in
a foothold stands wholly on its face; this is what the paper's ground-truth footholds do, which
"account for the width and length of the foot separately" (Section VIII-A, Fig. 12).
Terrains come from YAML files (``hw_config/terrains/``) or from seeded generators: ``flat``,
``stairs``, ``beam``, ``stones`` (the paper's Table I stepping stones), ``blocks``, and
QuadPiPS' ``ramped_stones`` (Table I's stones with tilted tops) and ``winding_beam``. The
robot starts at the origin facing +x, standing at ``start_z``.
"""

from __future__ import annotations

import dataclasses
import inspect
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np

from lcmtypes import foothold_set_t
from runtime.codecs import footholds_to_msg
from runtime.errors import ConfigError
from runtime.geometry import Foothold
from runtime.params import read, spec

#: Table I of Acosta & Posa: uniform bounds of the stepping-stone samples (metres).
STONE_XY_OFFSET = 0.05
STONE_Z_OFFSET = 0.075
STONE_SIZE_EXTRA = 0.05
STONE_SPACING_EXTRA = 0.21  # nominal centre spacing = d_min + 21 cm
STONE_ROWS = 5  # along x, the walking direction
STONE_COLS = 3  # across y


@dataclass(frozen=True)
class Box:
    """A box: centre (world), full side lengths, and its attitude: yaw about z, then pitch about
    the new y and roll about the newest x (rad; R = Rz(yaw) Ry(pitch) Rx(roll)). Untilted
    boxes (pitch = roll = 0) stand upright with a level top; a tilted one's top is a ramp."""

    center: tuple[float, float, float]
    size: tuple[float, float, float]
    yaw: float = 0.0
    pitch: float = 0.0
    roll: float = 0.0

    @property
    def tilted(self) -> bool:
        return self.pitch != 0.0 or self.roll != 0.0

    @cached_property
    def rotation(self) -> np.ndarray:
        """R = Rz(yaw) Ry(pitch) Rx(roll): the box's axes (columns) in the world."""
        cy, sy = math.cos(self.yaw), math.sin(self.yaw)
        cp, sp = math.cos(self.pitch), math.sin(self.pitch)
        cr, sr = math.cos(self.roll), math.sin(self.roll)
        return np.array([[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                         [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                         [-sp, cp * sr, cp * cr]])

    @property
    def quat_wxyz(self) -> tuple[float, float, float, float]:
        """The attitude as a unit quaternion (w, x, y, z): MuJoCo's order."""
        cy, sy = math.cos(0.5 * self.yaw), math.sin(0.5 * self.yaw)
        cp, sp = math.cos(0.5 * self.pitch), math.sin(0.5 * self.pitch)
        cr, sr = math.cos(0.5 * self.roll), math.sin(0.5 * self.roll)
        return (cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy,
                cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy)

    @property
    def top_z(self) -> float:
        """Height of the top face's centre (of the whole top for an untilted box)."""
        return self.center[2] + 0.5 * self.size[2] * float(self.rotation[2, 2])

    @property
    def top_normal(self) -> np.ndarray:
        """The top face's unit upward normal: the box's z axis."""
        return self.rotation[:, 2].copy()

    def top_corners(self, margin: float = 0.0) -> np.ndarray:
        """The top face's corners shrunk by ``margin`` (in the face), counter-clockwise from
        above, (4, 3)."""
        hx = max(0.5 * self.size[0] - margin, 0.0)
        hy = max(0.5 * self.size[1] - margin, 0.0)
        local = np.array([[hx, hy], [-hx, hy], [-hx, -hy], [hx, -hy]])
        if self.tilted:
            face = np.column_stack((local, np.full(4, 0.5 * self.size[2])))
            return face @ self.rotation.T + np.array(self.center)
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        rot = np.array([[c, -s], [s, c]])
        xy = local @ rot.T + np.array(self.center[:2])
        return np.column_stack([xy, np.full(4, self.top_z)])

    def top_height_at(self, x: float, y: float) -> float | None:
        """z of the top face above (x, y), None when (x, y) is not under it."""
        if not self.tilted:
            c, s = math.cos(self.yaw), math.sin(self.yaw)
            dx, dy = x - self.center[0], y - self.center[1]
            inside = (abs(c * dx + s * dy) <= 0.5 * self.size[0]
                      and abs(-s * dx + c * dy) <= 0.5 * self.size[1])
            return self.top_z if inside else None
        u, v, z0 = self._top_frame
        r = self.rotation
        dx, dy = x - z0[0], y - z0[1]
        a = u[0] * dx + u[1] * dy  # the face's (u, v) above (x, y): the inverse of its
        b = v[0] * dx + v[1] * dy  # 2 x 2 horizontal map, precomputed
        if abs(a) > 0.5 * self.size[0] or abs(b) > 0.5 * self.size[1]:
            return None
        return z0[2] + float(r[2, 0]) * a + float(r[2, 1]) * b

    @cached_property
    def _top_frame(self) -> tuple[tuple[float, float], tuple[float, float],
                                  tuple[float, float, float]]:
        """The rows of the inverse of the top face's horizontal map (its x and y axes' x, y)
        and the face's centre: (x, y) -> the face's own (u, v) in ``top_height_at``."""
        r = self.rotation
        m = np.linalg.inv(r[:2, :2])
        centre = np.array(self.center) + 0.5 * self.size[2] * r[:, 2]
        return ((float(m[0, 0]), float(m[0, 1])), (float(m[1, 0]), float(m[1, 1])),
                (float(centre[0]), float(centre[1]), float(centre[2])))


@dataclass(frozen=True)
class Terrain:
    """Boxes to add to the model, the ground plane height (None: no ground) and footholds."""

    name: str
    boxes: tuple[Box, ...] = ()
    footholds: tuple[Foothold, ...] = ()
    ground_z: float | None = 0.0
    start_z: float = 0.0  # height of the surface under the robot's feet at start
    seed: int | None = None
    params: Mapping[str, Any] = field(default_factory=dict)
    #: the footholds before they were shrunk for the foot (``foot_eroded``); empty if they
    #: were not: where a foot centre may land, as opposed to where the controller should aim
    surfaces: tuple[Foothold, ...] = ()
    #: the course's centre line (x, y) from the start to the end, for an operator that steers
    #: along it (``winding_beam``); empty: the x axis
    path: tuple[tuple[float, float], ...] = ()
    #: per foothold, the heading a foot faces on it (rad; ``foot_eroded`` shrinks each for
    #: a foot turned so): along a winding beam's pieces; empty: every foot faces +x
    foot_headings: tuple[float, ...] = ()

    @property
    def landing_surfaces(self) -> tuple[Foothold, ...]:
        """The faces (less the margin) a foot centre may land on, for judging a footstep."""
        return self.surfaces or self.footholds

    def height_at(self, x: float, y: float) -> float:
        """Height of the terrain under (x, y): the highest box top there, else the ground
        plane (-inf over a pit). For judging falls (pelvis height over the ground under it)."""
        z = self.ground_z if self.ground_z is not None else -math.inf
        for b in self.boxes:
            top = b.top_height_at(x, y)
            if top is not None and top > z:
                z = top
        return z


def foot_eroded(terrain: Terrain, half_length: float, half_width: float) -> Terrain:
    """``terrain`` with its footholds shrunk for the foot (``Foothold.eroded``: the foot centres
    for which a ``2 half_length`` x ``2 half_width`` foot facing +x, or the foothold's
    ``foot_headings``, lies wholly on the face); footholds the foot does not fit on are
    dropped. The unshrunk ones stay as ``surfaces``."""
    if half_length <= 0.0 and half_width <= 0.0:
        return terrain
    yaws = terrain.foot_headings or (0.0,) * len(terrain.footholds)
    holds = [f.eroded(half_length, half_width, y) for f, y in zip(terrain.footholds, yaws,
                                                                      strict=True)]
    params = {**terrain.params, "foot_half_size": (half_length, half_width)}
    return replace(terrain, footholds=tuple(f for f in holds if f is not None),
                   surfaces=terrain.footholds, params=params,
                   foot_headings=tuple(y for f, y in zip(holds, yaws, strict=True)
                                       if f is not None) if terrain.foot_headings else ())


def _top_foothold(box: Box, margin: float) -> Foothold:
    """The box's top face less ``margin``: a level foothold, or on a tilted box's plane."""
    if min(box.size[0], box.size[1]) <= 2.0 * margin:
        raise ValueError(f"a box of {box.size[0]} x {box.size[1]} m has no top face left "
                         f"inside a foothold margin of {margin} m")
    corners = box.top_corners(margin)
    if not box.tilted:
        return Foothold.from_ccw(corners[:, :2], (0.0, 0.0, 1.0), box.top_z)
    n = box.top_normal
    return Foothold.from_ccw(corners[:, :2], n, float(n @ corners.mean(axis=0)))


def _rect_foothold(x0: float, x1: float, y0: float, y1: float, z: float, margin: float) -> Foothold:
    box = Box(center=(0.5 * (x0 + x1), 0.5 * (y0 + y1), z - 0.5), size=(x1 - x0, y1 - y0, 1.0))
    return _top_foothold(box, margin)


def _slab(x0: float, x1: float, width: float, top: float, bottom: float, y: float = 0.0) -> Box:
    """A box spanning x0..x1, centred on y, from ``bottom`` up to ``top``."""
    return Box(
        center=(0.5 * (x0 + x1), y, 0.5 * (top + bottom)),
        size=(x1 - x0, width, top - bottom),
    )


def foothold_set_msg(terrain: Terrain, utime: int = 0) -> foothold_set_t:
    """The terrain's ground-truth footholds as a foothold set (what S3 would publish with
    perfect perception), for controllers run with perfect terrain knowledge."""
    return footholds_to_msg(terrain.footholds, utime, map_seq=-1,  # not from an elevation map
                            status_text=f"ground truth: {terrain.name}")


# -- generators ----------------------------------------------------------------------------


def flat(margin: float = 0.02, extent: float = 10.0) -> Terrain:
    """The ground plane at z = 0; one foothold covering ``extent`` metres around the start."""
    fh = _rect_foothold(-extent, extent, -extent, extent, 0.0, margin)
    return Terrain("flat", footholds=(fh,), params={"margin": margin, "extent": extent})


def stairs(
    rise: float = 0.15,
    depth: float = 0.27,
    count: int = 6,
    width: float = 2.0,
    start_length: float = 0.6,
    landing: float = 1.5,
    margin: float = 0.02,
) -> Terrain:
    """Ground, then ``count`` steps up (solid boxes from the ground), then a landing."""
    boxes: list[Box] = []
    holds = [_rect_foothold(-2.0, start_length, -width / 2, width / 2, 0.0, margin)]
    x = start_length
    for i in range(1, count + 1):
        length = depth if i < count else landing
        box = _slab(x, x + length, width, i * rise, 0.0)
        boxes.append(box)
        holds.append(_top_foothold(box, margin))
        x += length
    params = dict(rise=rise, depth=depth, count=count, width=width, start_length=start_length,
                  landing=landing, margin=margin)
    return Terrain("stairs", boxes=tuple(boxes), footholds=tuple(holds), params=params)


def beam(
    width: float = 0.23,
    length: float = 8.0,
    platform: float = 1.0,
    pit_depth: float = 0.5,
    margin: float = 0.02,
) -> Terrain:
    """A start platform, a beam of ``width`` x ``length`` and an end platform over a pit."""
    bottom = -pit_depth
    start = _slab(-platform, 0.3, 1.5, 0.0, bottom)
    beam_box = _slab(0.3, 0.3 + length, width, 0.0, bottom)
    end = _slab(0.3 + length, 0.3 + length + platform, 1.5, 0.0, bottom)
    boxes = (start, beam_box, end)
    params = dict(width=width, length=length, platform=platform, pit_depth=pit_depth, margin=margin)
    return Terrain("beam", boxes=boxes, footholds=tuple(_top_foothold(b, margin) for b in boxes),
                   ground_z=bottom, params=params)


@dataclass(frozen=True)
class StoneSample:
    """One stepping stone as drawn from Table I: grid cell, nominal centre and the draws."""

    row: int
    col: int
    nominal_xy: tuple[float, float]
    offset: tuple[float, float, float]  # x, y, z offsets
    length: float  # along x
    width: float  # along y


def sample_stones(rng: np.random.Generator, d_min: float, first_x: float) -> list[StoneSample]:
    """Draw the 5 x 3 grid of stepping stones with the bounds of Table I (uniform)."""
    spacing = d_min + STONE_SPACING_EXTRA
    out: list[StoneSample] = []
    for row in range(STONE_ROWS):
        for col in range(STONE_COLS):
            nominal = (first_x + row * spacing, (col - (STONE_COLS - 1) / 2) * spacing)
            dx, dy = rng.uniform(-STONE_XY_OFFSET, STONE_XY_OFFSET, size=2)
            dz = rng.uniform(-STONE_Z_OFFSET, STONE_Z_OFFSET)
            length, width = rng.uniform(d_min, d_min + STONE_SIZE_EXTRA, size=2)
            out.append(StoneSample(row, col, nominal, (float(dx), float(dy), float(dz)),
                                   float(length), float(width)))
    return out


def stones(
    d_min: float = 0.35,
    seed: int = 0,
    platform: float = 1.0,
    pit_depth: float = 0.5,
    margin: float = 0.02,
) -> Terrain:
    """The paper's random stepping stones (Section VIII-A1, Table I) between two platforms."""
    return _stepping_stones("stones", d_min, seed, platform, pit_depth, margin, 0.0)


def ramped_stones(
    d_min: float = 0.35,
    seed: int = 0,
    max_tilt_deg: float = 10.0,
    platform: float = 1.0,
    pit_depth: float = 0.5,
    margin: float = 0.02,
) -> Terrain:
    """``stones`` (the same stones for the same d_min and seed) with each stone's top tilted by
    a pitch and a roll drawn uniformly within +-``max_tilt_deg``, about the top's centre:
    QuadPiPS' ramped stepping stones (Asselmeier et al., Section VIII-B, Fig. 13 g; its 10 deg
    is their ramps' incline, VIII-C). The footholds lie on the tilted tops."""
    return _stepping_stones("ramped_stones", d_min, seed, platform, pit_depth, margin,
                            max_tilt_deg)


def _stepping_stones(name: str, d_min: float, seed: int, platform: float, pit_depth: float,
                     margin: float, max_tilt_deg: float) -> Terrain:
    """Table I's stones between two platforms; with ``max_tilt_deg`` > 0, each top tilted by
    (pitch, roll) drawn after the stones from the same generator."""
    rng = np.random.default_rng(seed)
    bottom = -pit_depth
    spacing = d_min + STONE_SPACING_EXTRA
    start_edge = 0.3
    first_x = start_edge + STONE_SPACING_EXTRA + d_min / 2
    samples = sample_stones(rng, d_min, first_x)
    tilts = (rng.uniform(-max_tilt_deg, max_tilt_deg, size=(len(samples), 2))
             if max_tilt_deg > 0.0 else np.zeros((len(samples), 2)))
    grid_width = (STONE_COLS - 1) * spacing + d_min + 0.2
    boxes = [_slab(start_edge - platform, start_edge, grid_width, 0.0, bottom)]
    for s, (pitch, roll) in zip(samples, np.radians(tilts), strict=True):
        top = s.offset[2]
        size = (s.length, s.width, top - bottom)
        centre = np.array((s.nominal_xy[0] + s.offset[0], s.nominal_xy[1] + s.offset[1],
                           0.5 * (top + bottom)))
        if max_tilt_deg > 0.0:  # about the top's centre: the box hangs from it, tilted
            axis = Box((0.0, 0.0, 0.0), size, 0.0, float(pitch), float(roll)).top_normal
            centre = np.array((centre[0], centre[1], top)) - 0.5 * size[2] * axis
        boxes.append(Box(center=(float(centre[0]), float(centre[1]), float(centre[2])),
                         size=size, pitch=float(pitch), roll=float(roll)))
    end_edge = first_x + (STONE_ROWS - 1) * spacing + d_min / 2 + STONE_SPACING_EXTRA
    boxes.append(_slab(end_edge, end_edge + platform, grid_width, 0.0, bottom))
    params: dict[str, Any] = dict(d_min=d_min, seed=seed, platform=platform,
                                  pit_depth=pit_depth, margin=margin, samples=samples)
    if max_tilt_deg > 0.0:
        params |= {"max_tilt_deg": max_tilt_deg,
                   "tilts_deg": [(float(p), float(r)) for p, r in tilts]}
    return Terrain(name, boxes=tuple(boxes),
                   footholds=tuple(_top_foothold(b, margin) for b in boxes),
                   ground_z=bottom, seed=seed, params=params)


def winding_beam(
    width: float = 0.23,
    segments: int = 6,
    segment_length: float = 1.0,
    turn_min_deg: float = 20.0,
    turn_max_deg: float = 30.0,
    max_heading_deg: float = 30.0,
    seed: int = 0,
    platform: float = 1.0,
    pit_depth: float = 0.5,
    margin: float = 0.02,
) -> Terrain:
    """A beam of ``segments`` straight pieces that turn left and right, from a start platform
    to an end platform over a pit: QuadPiPS' winding balance beam (Asselmeier et al., Section
    VIII-B, Fig. 13 j; the paper gives no dimensions). The first piece turns off the start
    platform's heading (+x), each next one off the one before, by a uniform draw in
    [turn_min_deg, turn_max_deg] to a random side, the other side where that would head beyond
    +-``max_heading_deg``. Each piece runs on past its joints far enough that the outer edges
    of neighbours meet ((w/2) tan(turn/2); into a platform (w/2) tan|heading|): one connected
    surface. ``path`` is its centre line, platform to platform."""
    rng = np.random.default_rng(seed)
    bottom = -pit_depth
    headings: list[float] = []
    h = 0.0
    for _ in range(segments):
        turn = float(rng.uniform(turn_min_deg, turn_max_deg)) * (1.0 if rng.random() < 0.5
                                                                 else -1.0)
        if abs(h + turn) > max_heading_deg:
            turn = -turn
        h += turn
        headings.append(h)
    joints = [np.array((0.3, 0.0))]
    for hd in headings:
        joints.append(joints[-1] + segment_length * np.array((math.cos(math.radians(hd)),
                                                              math.sin(math.radians(hd)))))
    start = _slab(-platform, 0.3, 1.5, 0.0, bottom)
    end_x, end_y = (float(v) for v in joints[-1])
    end = _slab(end_x, end_x + platform, 1.5, 0.0, bottom, y=end_y)
    around = [0.0, *headings, 0.0]  # the platforms' heading either side
    pieces = []
    for i, hd in enumerate(headings):
        ext = []
        for other, platform_side in ((around[i], i == 0), (around[i + 2], i == segments - 1)):
            d = math.radians(abs(hd - other))
            ext.append(0.5 * width * (math.tan(d) if platform_side else math.tan(0.5 * d)))
        u = np.array((math.cos(math.radians(hd)), math.sin(math.radians(hd))))
        a, b = joints[i] - ext[0] * u, joints[i + 1] + ext[1] * u
        mid = 0.5 * (a + b)
        pieces.append(Box(center=(float(mid[0]), float(mid[1]), 0.5 * bottom),
                          size=(float(np.linalg.norm(b - a)), width, -bottom),
                          yaw=math.radians(hd)))
    boxes = (start, *pieces, end)
    path = ((-0.5, 0.0), *((float(p[0]), float(p[1])) for p in joints),
            (end_x + platform, end_y))
    # Each joint's own foothold (ours): the pieces' faces, shrunk for a foot facing along
    # them, stop short of a joint by the foot's half length, leaving gaps of ~16 cm along the
    # beam where the surface is whole (a stop was measured there with ground truth). A
    # rectangle about the joint along the turn's bisector, half length ``a``, lies on the two
    # pieces' union where its half width c meets c cos(t/2) + a sin(t/2) <= w/2 - margin
    # (turn t; beside a platform, heading along the piece, c <= w/2 - margin).
    joint_holds, joint_yaws = [], []
    a = 0.5 * width + 0.05
    for i, p in enumerate(joints):
        h0, h1 = math.radians(around[i]), math.radians(around[i + 1])
        half = 0.5 * abs(h1 - h0)
        platform_side = i in (0, segments)
        yaw = h1 if i == 0 else h0 if i == segments else 0.5 * (h0 + h1)
        room = 0.5 * width - margin
        c = room if platform_side else (room - a * math.sin(half)) / math.cos(half)
        if c <= 0.0:
            continue
        u = np.array((math.cos(yaw), math.sin(yaw)))
        n = np.array((-u[1], u[0]))
        corners = np.array([p - a * u - c * n, p + a * u - c * n, p + a * u + c * n,
                            p - a * u + c * n])
        joint_holds.append(Foothold.from_ccw(corners, (0.0, 0.0, 1.0), 0.0))
        joint_yaws.append(yaw)
    params: dict[str, Any] = dict(
        width=width, segments=segments, segment_length=segment_length,
        turn_min_deg=turn_min_deg, turn_max_deg=turn_max_deg, max_heading_deg=max_heading_deg,
        seed=seed, platform=platform, pit_depth=pit_depth, margin=margin,
        headings_deg=headings)
    return Terrain("winding_beam", boxes=boxes,
                   footholds=(*(_top_foothold(b, margin) for b in boxes), *joint_holds),
                   ground_z=bottom, seed=seed, params=params, path=path,
                   foot_headings=(0.0, *(math.radians(hd) for hd in headings), 0.0,
                                  *joint_yaws))


def blocks(
    count: int = 12,
    seed: int = 0,
    area: tuple[float, float, float, float] = (0.6, 4.0, -1.0, 1.0),
    size_min: float = 0.25,
    size_max: float = 0.6,
    height_max: float = 0.12,
    max_yaw_deg: float = 30.0,
    margin: float = 0.02,
) -> Terrain:
    """Random, non-overlapping blocks on the ground ahead of the robot (start area clear).

    Footholds: each block's top face, plus the clear ground rectangle around the start (the
    ground between blocks is not convex, so it is left out of the ground truth). Fewer than
    ``count`` blocks are placed if the area cannot hold them.
    """
    rng = np.random.default_rng(seed)
    x0, x1, y0, y1 = area
    boxes: list[Box] = []
    circles: list[tuple[float, float, float]] = []
    for _ in range(count * 50):  # rejection sampling: blocks never overlap
        if len(boxes) == count:
            break
        sx, sy = rng.uniform(size_min, size_max, size=2)
        h = rng.uniform(0.02, height_max)
        cx, cy = rng.uniform(x0, x1), rng.uniform(y0, y1)
        yaw = math.radians(rng.uniform(-max_yaw_deg, max_yaw_deg))
        r = 0.5 * math.hypot(sx, sy)
        if any(math.hypot(cx - x, cy - y) < r + rr for x, y, rr in circles):
            continue
        circles.append((float(cx), float(cy), r))
        boxes.append(Box(center=(float(cx), float(cy), float(h / 2)),
                         size=(float(sx), float(sy), float(h)), yaw=float(yaw)))
    clear = max(0.0, x0 - size_max * 0.75)
    holds = [_rect_foothold(-1.5, clear, -1.0, 1.0, 0.0, margin)]
    holds += [_top_foothold(b, margin) for b in boxes]
    params = dict(count=count, seed=seed, area=area, size_min=size_min, size_max=size_max,
                  height_max=height_max, max_yaw_deg=max_yaw_deg, margin=margin)
    return Terrain("blocks", boxes=tuple(boxes), footholds=tuple(holds), seed=seed, params=params)


def from_boxes(
    boxes: list[Box], ground_z: float | None = 0.0, start_z: float = 0.0, margin: float = 0.02
) -> Terrain:
    """A hand-written terrain: the given boxes; footholds are their top faces."""
    return Terrain("boxes", boxes=tuple(boxes),
                   footholds=tuple(_top_foothold(b, margin) for b in boxes),
                   ground_z=ground_z, start_z=start_z, params={"margin": margin})


#: generator name -> (function, parameter defaults with their types)
GENERATORS: dict[str, Callable[..., Terrain]] = {
    "flat": flat, "stairs": stairs, "beam": beam, "stones": stones, "blocks": blocks,
    "ramped_stones": ramped_stones, "winding_beam": winding_beam,
}


def generate(name: str, foot_half_size: tuple[float, float] = (0.0, 0.0),
             **params: Any) -> Terrain:
    """Run the generator called ``name`` with ``params`` (see ``GENERATORS``), its footholds
    shrunk for a foot of ``foot_half_size`` (``foot_eroded``)."""
    return foot_eroded(GENERATORS[name](**params), *foot_half_size)


# -- YAML ----------------------------------------------------------------------------------
# A terrain file, read by runtime.params: ``TerrainFile`` first (which terrain, the foot,
# the margin), then the whole file as ``BoxesFile`` or as its generator's file class,
# ``GENERATED_FILES[name]`` (its ``params`` a dataclass of the generator's keyword arguments,
# their defaults the generator's own).

#: generator parameters that are integers, and those that may be zero or negative
_INT_PARAMS = {"count", "seed", "segments"}
_MAY_BE_ZERO_OR_NEG = {"seed", "max_yaw_deg", "margin", "start_length", "turn_min_deg"}
TERRAIN_NAMES = (*GENERATORS, "boxes")


@dataclass(frozen=True, kw_only=True)
class TerrainFile:
    """The keys of every terrain file."""

    terrain: str = spec(choices=TERRAIN_NAMES)  # (required)
    foothold_margin: float = spec(0.02, lo=0.0, unit="m")
    #: [half_length, half_width] of the foot: the footholds shrink by it (``foot_eroded``)
    foot_half_size: tuple[float, float] = spec((0.0, 0.0), lo=0.0, unit="m")


@dataclass(frozen=True)
class BoxSpec:
    """One box of ``terrain: boxes``: centre (world), full side lengths, yaw about z."""

    center: tuple[float, float, float] = spec(unit="m")  # (required)
    size: tuple[float, float, float] = spec(lo=0.0, lo_open=True, unit="m")  # (required)
    yaw_deg: float = spec(0.0, unit="deg")
    pitch_deg: float = spec(0.0, lo=-60.0, hi=60.0, unit="deg")  # a ramp (Box's attitude)
    roll_deg: float = spec(0.0, lo=-60.0, hi=60.0, unit="deg")


@dataclass(frozen=True, kw_only=True)
class BoxesFile(TerrainFile):
    """``terrain: boxes``: hand-written boxes; footholds are their top faces."""

    boxes: tuple[BoxSpec, ...] = spec()  # (required, at least one)
    ground_z: float | None = spec(0.0, unit="m")  # None: no ground plane (a pit)
    start_z: float = spec(0.0, unit="m")

    def __post_init__(self) -> None:
        if not self.boxes:
            raise ConfigError("<BoxesFile>", "boxes", "must be a non-empty list of boxes",
                              "a list of {center, size, yaw_deg}")


def _param_field(name: str, default: Any) -> tuple[str, Any, Any]:
    """A generator's keyword argument as a field: its type and range from its default."""
    lo, lo_open = (None, False) if name in _MAY_BE_ZERO_OR_NEG else (0.0, True)
    if name in _INT_PARAMS:
        tp: Any = int
    elif isinstance(default, tuple):
        tp, lo = tuple[(float,) * len(default)], None  # type: ignore[misc]
    else:
        tp = float
    return name, tp, spec(default, lo=lo, lo_open=lo_open)


def _blocks_check(self: Any) -> None:
    """``blocks``' params: an area of positive extent, size_min <= size_max."""
    x0, x1, y0, y1 = self.area
    if x0 >= x1 or y0 >= y1:
        raise ConfigError("<BlocksParams>", "area", "needs x_min < x_max and y_min < y_max",
                          "[x_min, x_max, y_min, y_max]")
    if self.size_min > self.size_max:
        raise ConfigError("<BlocksParams>", "size_min",
                          f"{self.size_min} is above size_max {self.size_max}",
                          f"(0.0, {self.size_max}]")


def _ramped_stones_check(self: Any) -> None:
    """``ramped_stones``' params: a tilt a foot can stand on."""
    if not self.max_tilt_deg <= 30.0:
        raise ConfigError("<Ramped_stonesParams>", "max_tilt_deg",
                          f"{self.max_tilt_deg} deg is steeper than a foot holds",
                          "(0, 30] deg")


def _winding_beam_check(self: Any) -> None:
    """``winding_beam``' params: turns a heading within +-max_heading_deg can always take."""
    if not 0.0 <= self.turn_min_deg <= self.turn_max_deg:
        raise ConfigError("<Winding_beamParams>", "turn_min_deg",
                          f"{self.turn_min_deg} is not within [0, turn_max_deg "
                          f"{self.turn_max_deg}]", f"[0, {self.turn_max_deg}] deg")
    if not (self.turn_max_deg <= 2.0 * self.max_heading_deg and self.max_heading_deg < 90.0):
        raise ConfigError("<Winding_beamParams>", "max_heading_deg",
                          f"{self.max_heading_deg} deg: a turn of turn_max_deg "
                          f"{self.turn_max_deg} must fit within +-max_heading_deg either way",
                          f"[{0.5 * self.turn_max_deg}, 90) deg")


#: generator name -> the check of its params beyond each value's range
_PARAMS_CHECKS: dict[str, Callable[[Any], None]] = {
    "blocks": _blocks_check, "ramped_stones": _ramped_stones_check,
    "winding_beam": _winding_beam_check,
}


def _kwargs(fn: Callable[..., Terrain]) -> dict[str, Any]:
    """A generator's keyword arguments and their defaults."""
    return {n: p.default for n, p in inspect.signature(fn).parameters.items()}


def _params_class(name: str, fn: Callable[..., Terrain]) -> type:
    """A frozen dataclass of ``fn``'s keyword arguments but ``margin`` (``foothold_margin``)
    and ``seed`` (a key of the file's own)."""
    args = [_param_field(n, d) for n, d in _kwargs(fn).items() if n not in ("margin", "seed")]
    ns = {"__post_init__": _PARAMS_CHECKS[name]} if name in _PARAMS_CHECKS else {}
    return dataclasses.make_dataclass(f"{name.capitalize()}Params", args, frozen=True,
                                      namespace=ns)


#: generator name -> the dataclass of its ``params:`` in a terrain file
GENERATOR_PARAMS: dict[str, type] = {n: _params_class(n, fn) for n, fn in GENERATORS.items()}


def _generated_file(name: str) -> type:
    """The file of terrain ``name``: ``params`` its generator's, and ``seed`` if it has one."""
    extra: list[tuple[str, Any, Any]] = [
        ("params", GENERATOR_PARAMS[name], spec(default_factory=GENERATOR_PARAMS[name]))]
    defaults = _kwargs(GENERATORS[name])
    if "seed" in defaults:
        extra.append(("seed", int, spec(defaults["seed"], lo=0)))
    return dataclasses.make_dataclass(f"{name.capitalize()}File", extra, bases=(TerrainFile,),
                                      frozen=True, kw_only=True)


#: generator name -> the dataclass of a terrain file of it
GENERATED_FILES: dict[str, type] = {n: _generated_file(n) for n in GENERATORS}


def load_terrain(path: str | Path) -> Terrain:
    """Read a terrain YAML file; raises ``ConfigError`` naming the file and key on bad input.

    Either ``terrain: NAME`` (a generator, with ``params`` and, for a random one, ``seed``)
    or ``terrain: boxes`` with a ``boxes`` list of ``{center, size, yaw_deg}``; either may
    give ``foot_half_size: [half_length, half_width]`` to shrink the footholds for the foot.
    """
    from runtime.config import load_yaml

    file = str(path)
    doc = load_yaml(Path(path))
    # which terrain first (required, a known one): its other keys depend on it
    name = read(TerrainFile, {k: v for k, v in doc.items() if k == "terrain"}, file).terrain
    if name == "boxes":
        b = read(BoxesFile, doc, file)
        boxes = [Box(x.center, x.size, math.radians(x.yaw_deg), math.radians(x.pitch_deg),
                     math.radians(x.roll_deg)) for x in b.boxes]
        terrain = from_boxes(boxes, ground_z=b.ground_z, start_z=b.start_z,
                             margin=b.foothold_margin)
        return foot_eroded(terrain, *b.foot_half_size)
    if "seed" in doc and "seed" not in _kwargs(GENERATORS[name]):
        random = [n for n, fn in GENERATORS.items() if "seed" in _kwargs(fn)]
        raise ConfigError(file, "seed", f"terrain {name!r} is not random", ", ".join(random))
    g = read(GENERATED_FILES[name], doc, file)
    kwargs = {f.name: getattr(g.params, f.name) for f in dataclasses.fields(g.params)}
    if hasattr(g, "seed"):
        kwargs["seed"] = g.seed
    return foot_eroded(GENERATORS[name](margin=g.foothold_margin, **kwargs), *g.foot_half_size)
