"""One codec per message that carries geometry: footholds, elevation maps and the guide's plan
<-> LCM messages.

``foothold_set_t`` (S3's FOOTHOLDS, or the sim's ground truth of its terrain) carries each
convex foothold as its plane, its half-spaces and its corners (``runtime.geometry``);
``elevation_map_t`` (perception's ELEVATION_MAP) carries named float32 layers of one grid;
``guide_plan_t`` (the SLIP guide's GUIDE_PLAN) its upcoming steps and the footholds they are
on (``GuidePlan``).
Each message has here the one function that builds it, the one that reads it back and the
check of its own consistency that the runners' edge validation applies to every input
(``runtime.validate``): a message that passes the check always decodes.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from lcmtypes import elevation_map_t, foothold_set_t, foothold_t, guide_plan_t

from .geometry import Foothold

#: ``foothold_set_t.status``
FOOTHOLDS_OK, FOOTHOLDS_PREVIOUS, FOOTHOLDS_EMPTY = 0, 1, 2
#: ``elevation_map_t.status``
MAP_OK, MAP_STALE, MAP_NO_DATA = 0, 1, 2


def footholds_to_msg(footholds: Iterable[Foothold], utime: int = 0, map_seq: int = -1,
                     status_text: str = "", previous: bool = False) -> foothold_set_t:
    """A foothold set (world frame) stamped with ``utime`` and the map it came from
    (``map_seq``, -1 for none); status: previous set kept, else ok or empty."""
    out = foothold_set_t()
    out.header.utime = utime
    out.map_seq = map_seq
    out.footholds = [_foothold_to_msg(f) for f in footholds]
    out.num_footholds = len(out.footholds)
    if previous:
        out.status = FOOTHOLDS_PREVIOUS
    else:
        out.status = FOOTHOLDS_OK if out.num_footholds else FOOTHOLDS_EMPTY
    out.status_text = status_text
    return out


def _foothold_to_msg(f: Foothold) -> foothold_t:
    """One polygon as ``foothold_t``: plane, half-spaces, corners."""
    m = foothold_t()
    m.normal = f.normal.tolist()
    m.offset = float(f.offset)
    m.num_halfspaces = len(f.b)
    m.A = f.A.tolist()
    m.b = f.b.tolist()
    verts = f.vertices
    m.num_vertices = len(verts)
    m.vertices = verts.tolist()
    return m


def _foothold_from_msg(f: foothold_t) -> Foothold | None:
    """One ``foothold_t`` back from its plane and half-spaces (rows and normal scaled to unit
    length); None for a malformed polygon."""
    try:
        return Foothold(np.asarray(f.A, dtype=float), np.asarray(f.b, dtype=float),
                        np.asarray(f.normal, dtype=float), float(f.offset))
    except ValueError:
        return None


def footholds_from_msg(msg: foothold_set_t) -> list[Foothold]:
    """The set's footholds; a malformed polygon is skipped, not raised, so one bad polygon
    costs only itself."""
    out = [_foothold_from_msg(f) for f in msg.footholds[: msg.num_footholds]]
    return [f for f in out if f is not None]


class FootholdSetReader:
    """The footholds of the newest foothold set on a channel: the same list object until a set
    with a new ``header.seq`` comes (a solver's caches keyed by the list hold), and a set that
    decodes to nothing taken only when it says it is empty (status 2), not when its polygons
    all failed to decode."""

    def __init__(self, footholds: list[Foothold] | None = None) -> None:
        self.footholds: list[Foothold] = footholds if footholds is not None else []
        self.seq = -1  # header.seq of the set read last

    def read(self, msg: foothold_set_t | None) -> bool:
        """Take ``msg`` if it is a new set; whether the footholds changed."""
        if msg is None or msg.header.seq == self.seq:
            return False
        self.seq = msg.header.seq
        fresh = footholds_from_msg(msg)
        if fresh or msg.status == FOOTHOLDS_EMPTY:
            self.footholds = fresh
            return True
        return False


def _footholds_problem(footholds: Sequence[Any], what: str = "foothold") -> str | None:
    """Why a list of ``foothold_t`` is inconsistent (a polygon's half-spaces incomplete, its
    normal no direction), or None."""
    for k, f in enumerate(footholds):
        if len(f.b) != len(f.A) or len(f.A) < 3:
            return f"{what} {k} with {len(f.A)} half-space rows and {len(f.b)} offsets"
        if sum(x * x for x in f.normal) < 0.25:
            return f"{what} {k} with a normal of length < 0.5"
    return None


def foothold_set_problem(m: Any) -> str | None:
    """Why a foothold set is inconsistent (``_footholds_problem``), or None."""
    return _footholds_problem(m.footholds)


# -- guide_plan_t: the SLIP guide's plan ------------------------------------------------------
#: ``guide_plan_t.status`` and ``step_side``
GUIDE_OK, GUIDE_NO_PLAN = guide_plan_t.STATUS_OK, guide_plan_t.STATUS_NO_PLAN
SIDE_LEFT, SIDE_RIGHT = guide_plan_t.SIDE_LEFT, guide_plan_t.SIDE_RIGHT


@dataclass(frozen=True)
class GuidePlan:
    """The guide's plan as arrays: K upcoming steps in time order (contact point (K, 3),
    world; contact start and end (K,), sim time; side (K,), 0 left; ``region`` (K,), the
    index into ``regions`` of the foothold holding the point, -1 none), the CoM's mean
    horizontal velocity (2,) over the guide's velocity window (world), and the plan's
    status."""

    utime: int
    positions: np.ndarray
    start_s: np.ndarray
    end_s: np.ndarray
    sides: np.ndarray
    region: np.ndarray
    regions: tuple[Foothold, ...]
    nominal_velocity: np.ndarray
    status: int = GUIDE_OK
    status_text: str = ""
    footholds_seq: int = -1
    horizon_s: float = 0.0
    plan_wall_ms: float = 0.0
    qp_solves: int = 0

    @property
    def ok(self) -> bool:
        """A plan with steps in it."""
        return self.status == GUIDE_OK and len(self.positions) > 0


def no_guide_plan(utime: int, why: str) -> GuidePlan:
    """A plan-less message's content: no steps, ``why`` as its status."""
    return GuidePlan(utime, np.zeros((0, 3)), np.zeros(0), np.zeros(0), np.zeros(0, int),
                     np.zeros(0, int), (), np.zeros(2), GUIDE_NO_PLAN, why)


def guide_plan_to_msg(plan: GuidePlan) -> guide_plan_t:
    """The plan as ``guide_plan_t`` stamped with its ``utime``."""
    out = guide_plan_t()
    out.header.utime = plan.utime
    out.footholds_seq = int(plan.footholds_seq)
    out.num_steps = len(plan.positions)
    out.step_position = np.asarray(plan.positions, dtype=float).reshape(-1, 3).tolist()
    out.step_start_s = [float(x) for x in plan.start_s]
    out.step_end_s = [float(x) for x in plan.end_s]
    out.step_side = [int(x) for x in plan.sides]
    out.step_region = [int(x) for x in plan.region]
    out.regions = [_foothold_to_msg(f) for f in plan.regions]
    out.num_regions = len(out.regions)
    out.nominal_velocity = [float(x) for x in plan.nominal_velocity]
    out.horizon_s = float(plan.horizon_s)
    out.plan_wall_ms = float(plan.plan_wall_ms)
    out.qp_solves = int(plan.qp_solves)
    out.status = int(plan.status)
    out.status_text = plan.status_text
    return out


def guide_plan_from_msg(msg: guide_plan_t) -> GuidePlan:
    """The message's plan; a region that does not decode leaves its steps on none (-1)."""
    regions: list[Foothold] = []
    where: dict[int, int] = {}  # message index -> index into the decoded regions
    for k, f in enumerate(msg.regions[: msg.num_regions]):
        fh = _foothold_from_msg(f)
        if fh is not None:
            where[k] = len(regions)
            regions.append(fh)
    n = msg.num_steps
    return GuidePlan(
        msg.header.utime, np.asarray(msg.step_position[:n], dtype=float).reshape(-1, 3),
        np.asarray(msg.step_start_s[:n], dtype=float), np.asarray(msg.step_end_s[:n], float),
        np.asarray(msg.step_side[:n], dtype=int),
        np.array([where.get(int(r), -1) for r in msg.step_region[:n]], dtype=int),
        tuple(regions), np.asarray(msg.nominal_velocity, dtype=float), int(msg.status),
        msg.status_text, int(msg.footholds_seq), float(msg.horizon_s), float(msg.plan_wall_ms),
        int(msg.qp_solves))


def guide_plan_problem(m: Any) -> str | None:
    """Why a guide plan is inconsistent (a step's region out of the list, a step ending
    before it begins, a region as ``_footholds_problem``), or None."""
    for k in range(m.num_steps):
        if not -1 <= m.step_region[k] < m.num_regions:
            return f"step {k} on region {m.step_region[k]} of {m.num_regions}"
        if m.step_end_s[k] < m.step_start_s[k]:
            return f"step {k} ends at {m.step_end_s[k]} s before it begins"
    return _footholds_problem(m.regions, "region")


def elevation_map_to_msg(layers: Mapping[str, np.ndarray], resolution: float,
                         origin_xy: Sequence[float], utime: int = 0, status: int = MAP_OK,
                         status_text: str = "") -> elevation_map_t:
    """A map of named layers on one grid (rows along y; cell (0, 0) centred on ``origin_xy``),
    in the order given, as float32 little-endian."""
    shapes = {np.shape(g) for g in layers.values()}
    if len(shapes) != 1 or len(next(iter(shapes))) != 2:
        raise ValueError(f"an elevation map needs 2D layers of one shape, got {sorted(shapes)}")
    msg = elevation_map_t()
    msg.header.utime = utime
    msg.resolution = float(resolution)
    msg.rows, msg.cols = next(iter(shapes))
    msg.origin = [float(origin_xy[0]), float(origin_xy[1])]
    names = list(layers)
    msg.num_layers = len(names)
    msg.layer_names = names
    data = b"".join(np.ascontiguousarray(layers[n], dtype="<f4").tobytes() for n in names)
    msg.num_bytes = len(data)
    msg.data = data
    msg.status = status
    msg.status_text = status_text
    return msg


def elevation_map_from_msg(msg: elevation_map_t) -> dict[str, np.ndarray] | str:
    """The map's layers by name, (rows, cols) float32 views of its bytes, or why it has none."""
    why = elevation_map_problem(msg)
    if why is not None:
        return why
    cells = msg.rows * msg.cols
    flat = np.frombuffer(msg.data, dtype="<f4")
    return {name: flat[i * cells : (i + 1) * cells].reshape(msg.rows, msg.cols)
            for i, name in enumerate(msg.layer_names)}


def elevation_map_problem(m: Any) -> str | None:
    """Why an elevation map's grid, layers and bytes disagree (``elevation_map_t``'s own
    comment), or None."""
    if m.rows <= 0 or m.cols <= 0:
        return f"an elevation map of {m.rows} x {m.cols} cells"
    if not m.resolution > 0.0:
        return f"an elevation map with resolution {m.resolution}"
    if m.num_layers != len(m.layer_names) or m.num_layers <= 0:
        return f"an elevation map with {m.num_layers} layers named {len(m.layer_names)}"
    want = 4 * m.rows * m.cols * m.num_layers
    if len(m.data) != want:
        return (f"an elevation map of {len(m.data)} data bytes where {m.rows} x {m.cols} "
                f"cells x {m.num_layers} layers of float32 make {want}")
    return None


# -- robot_state_t: the fields the torque bridge reads without decoding ------------------------
def packet_seq_of(state: Any) -> int:
    """The target PC packet ``seq`` a robot_state_t was estimated from (for the torque's
    ``ack``)."""
    return int(state.packet_seq) & 0xFF


#: robot_state_t's last fields (packet_seq int32, packets_lost int64, packets_rejected int64)
#: have a fixed size, so packet_seq is a big-endian int32 this many bytes from the end of an
#: encoded state, whatever the lengths of the arrays and strings before it
#: (tests/state_estimator prove it against lcm-gen's encoding)
PACKET_SEQ_FROM_END = 4 + 8 + 8


def raw_utime_and_seq(data: bytes) -> tuple[int, int] | None:
    """``(header.utime, packet_seq & 0xFF)`` of an encoded robot_state_t, read from its bytes
    without decoding it (lcm-gen: fingerprint, then header.utime first); None when it is too
    short to hold them. Unchecked: a caller that acts on more than an ack decodes it."""
    if len(data) < 16 + PACKET_SEQ_FROM_END:
        return None
    utime = int.from_bytes(data[8:16], "big", signed=True)
    end = len(data) - PACKET_SEQ_FROM_END
    return utime, data[end + 3]  # the low byte of the big-endian int32
