"""The batcher: turns one batch of raw LCM messages into Rerun columns, one send per entity.

Called at most 30 times a second with everything the collector buffered since the last call.
High-rate channels are read header-first (``wire.read_headers``): hop latencies and the debug
scalars never need a full decode. Full decodes happen only for what is drawn, at a bounded
rate: the robot (``robot_hz`` of sim time), the newest plan of the batch, and the newest elevation
map and foothold set (``map_hz``). Scalar series (timing, latencies, solve times) are
sent less often, every ``scalar_flush_s``, as each send costs about 0.2 ms whatever its size;
they keep at most ``points_per_s`` points per second (of send time) per entity, above which
each point is the maximum of its time bucket, so spikes survive.

Timelines: ``sim_time`` (the message's ``header.utime``; the newest sim time seen when a
message has none, e.g. the supervisor's) and ``wall_time`` (the publisher's send time).
"""

from __future__ import annotations

import logging
import struct
import time
from collections import deque
from collections.abc import Callable, Iterable, Sequence
from typing import Any

import numpy as np
import pyarrow as pa
import rerun as rr

from lcmtypes import (
    applied_input_t,
    depth_frame_t,
    elevation_map_t,
    foothold_set_t,
    ground_truth_t,
    loop_timing_t,
    mpfc_debug_t,
    mpfc_output_t,
    osc_debug_t,
    robot_state_t,
    supervisor_status_t,
    torque_command_t,
)
from runtime.codecs import elevation_map_from_msg
from tools.dashboard.channels import Channels
from tools.dashboard.collector import ChannelStats
from tools.dashboard.hops import KeyTable, hop_latency_ms
from tools.dashboard.robot import FRAMES_ENTITY, LEG_CHAIN, WORLD_FRAME, Pose, Skeleton
from tools.dashboard.wire import Headers, fingerprint, read_headers

#: the span over which a loop's rate is taken from its TIMING reports (seconds)
RATE_WINDOW_S = 1.0

log = logging.getLogger(__name__)

#: Hops whose latency is shown, entity name -> what it measures.
HOPS = {
    "state_to_torque": "CASSIE_STATE -> OSC_TORQUE (same utime)",
    "sensor_to_applied": "CASSIE_STATE (sensor packet) -> CASSIE_INPUT (torque applied)",
    "state_to_plan": "NETWORK_CASSIE_STATE -> NETWORK_MPFC_PLAN (same utime)",
    "depth_to_map": "DEPTH -> ELEVATION_MAP (same utime)",
    "map_to_footholds": "ELEVATION_MAP -> FOOTHOLDS (map_seq)",
    "depth_to_footholds": "DEPTH -> FOOTHOLDS (utime, else through map_seq)",
}

#: Elevation-map layer names taken to be the S3 safe-terrain mask (1 safe, 0 unsafe).
MASK_LAYERS = ("s3_mask", "safe_mask", "safe", "s3", "mask")
MASK_UNSAFE, MASK_SAFE, MASK_UNKNOWN = 0, 1, 2

_FP = {t: fingerprint(t) for t in (
    robot_state_t, ground_truth_t, torque_command_t, applied_input_t, mpfc_output_t,
    depth_frame_t, elevation_map_t, foothold_set_t, mpfc_debug_t, osc_debug_t,
    loop_timing_t, supervisor_status_t,
)}
_DEPTH_LEAD = struct.Struct(">ii5d3d4d")  # width, height, fx, fy, cx, cy, scale, pos, quat
_MAP_LEAD = struct.Struct(">dii2di")  # resolution, rows, cols, origin, num_layers
_FOOTHOLDS_LEAD = struct.Struct(">qi")  # map_seq, num_footholds
_PLAN_LEAD = struct.Struct(">bb")  # gait_state, stance
_MPFC_DEBUG_LEAD = struct.Struct(">ddii")  # solve_wall_ms, optimizer_ms, nodes, num_footholds
_OSC_DEBUG_LEAD = struct.Struct(">ddii")  # tick_ms, solve_ms, qp_status, qp_iterations

# A viridis-like ramp for heights: dark blue (low) to yellow (high).
_RAMP = np.array([[68, 1, 84], [59, 82, 139], [33, 145, 140], [94, 201, 98], [253, 231, 37]])
_LUT = np.stack(
    [np.interp(np.linspace(0, 4, 256), np.arange(5), _RAMP[:, c]) for c in range(3)], axis=1
).astype(np.uint8)


def esc(part: str) -> str:
    """One entity-path part, escaped (process and loop names come from the bus)."""
    return rr.escape_entity_path_part(part or "_")


def reduce_max(
    sim_us: np.ndarray, wall_ns: np.ndarray, values: np.ndarray, bucket_ns: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One row per ``bucket_ns`` of wall time: the row holding the bucket's largest value
    (NaN counts as smallest), in the original order; rows may hold several values."""
    n = len(values)
    if n <= 1:
        return sim_us, wall_ns, values
    bucket = wall_ns // max(1, bucket_ns)
    if len(np.unique(bucket)) == n:
        return sim_us, wall_ns, values
    peak = values if values.ndim == 1 else np.max(
        np.where(np.isfinite(values), values, -np.inf), axis=1
    )
    peak = np.where(np.isfinite(peak), peak, -np.inf)
    order = np.lexsort((np.arange(n), peak, bucket))  # by bucket, then value, then position
    last_of_bucket = np.r_[bucket[order][1:] != bucket[order][:-1], True]
    keep = np.sort(order[last_of_bucket])
    return sim_us[keep], wall_ns[keep], values[keep]


def pick_by_period(
    utime: np.ndarray, period_us: int, last_us: int, cap: int
) -> tuple[list[int], int]:
    """Rows at least ``period_us`` of sim time apart (after ``last_us``); the last ``cap`` kept.

    A jump back in sim time (a restarted sim) restarts the spacing.
    """
    picked: list[int] = []
    for i, u in enumerate(utime.tolist()):
        if u - last_us >= period_us or u < last_us:
            picked.append(i)
            last_us = u
    return picked[-cap:], last_us


def colorize(values: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """RGB (..., 3) uint8 of ``values`` on the height ramp; NaN is black."""
    span = hi - lo if hi > lo else 1.0
    finite = np.isfinite(values)
    idx = np.clip((np.where(finite, values, lo) - lo) / span * 255.0, 0, 255).astype(np.uint8)
    rgb = _LUT[idx]
    rgb[~finite] = 0
    return rgb


def polygon_mask(
    vertices: Iterable[np.ndarray], origin: np.ndarray, resolution: float, shape: tuple[int, int]
) -> np.ndarray:
    """Boolean grid (rows = y, cols = x) of cells whose centres lie in any convex polygon's
    projection on the ground (vertices in either winding order)."""
    rows, cols = shape
    out = np.zeros(shape, dtype=bool)
    for v in vertices:
        if len(v) < 3:
            continue
        xy = np.asarray(v, dtype=np.float64)[:, :2]
        j0, i0 = np.floor((xy.min(axis=0) - origin) / resolution).astype(int)
        j1, i1 = np.ceil((xy.max(axis=0) - origin) / resolution).astype(int)
        i0, j0 = max(i0, 0), max(j0, 0)
        i1, j1 = min(i1, rows - 1), min(j1, cols - 1)
        if i0 > i1 or j0 > j1:
            continue
        ii, jj = np.mgrid[i0 : i1 + 1, j0 : j1 + 1]
        px = origin[0] + jj * resolution
        py = origin[1] + ii * resolution
        nxt = np.roll(xy, -1, axis=0)
        pos = np.ones(px.shape, dtype=bool)
        neg = np.ones(px.shape, dtype=bool)
        for (ax, ay), (bx, by) in zip(xy, nxt, strict=True):
            cross = (bx - ax) * (py - ay) - (by - ay) * (px - ax)
            pos &= cross >= -1e-9
            neg &= cross <= 1e-9
        out[i0 : i1 + 1, j0 : j1 + 1] |= pos | neg
    return out


class _Times:
    """A time column (``rr.TimeColumnLike``) built straight from numpy: ``rr.TimeColumn``
    costs about 30 us more per column, which adds up at 60 columns a batch."""

    def __init__(self, timeline: str, values: np.ndarray) -> None:
        self.timeline = timeline
        self.times = pa.array(values.astype(
            "timedelta64[ns]" if values.dtype.kind == "m" else "datetime64[ns]"
        ))

    def timeline_name(self) -> str:
        return self.timeline

    def as_arrow_array(self) -> pa.Array:
        return self.times


class _Column:
    """A component column (``rr.ComponentColumn``-like) from a prebuilt arrow array: the
    SDK's ``Transform3D.columns``, ``Points3D.columns`` and ``LineStrips3D.columns`` take
    ~0.2 ms a call, more than the send itself, and every robot frame needs four."""

    def __init__(self, descriptor: Any, array: pa.Array) -> None:
        self.descriptor = descriptor
        self.array = array

    def component_descriptor(self) -> Any:
        return self.descriptor

    def as_arrow_array(self) -> pa.Array:
        return self.array


def _template(columns: Any) -> tuple[dict[str, Any], dict[str, pa.DataType]]:
    """Component descriptors and arrow types by field name, from one ``Archetype.columns``
    call made once (so they follow the SDK's version)."""
    by_field = {c.component_descriptor().component.split(":")[-1]: c for c in columns}
    return ({k: c.component_descriptor() for k, c in by_field.items()},
            {k: c.as_arrow_array().type for k, c in by_field.items()})


_T3D, _T3D_TYPES = _template(rr.Transform3D.columns(
    translation=np.zeros((1, 3)), quaternion=[[0.0, 0.0, 0.0, 1.0]], child_frame=["a"],
    parent_frame=["b"]))
_P3D, _P3D_TYPES = _template(rr.Points3D.columns(positions=np.zeros((1, 3))))
_L3D, _L3D_TYPES = _template(rr.LineStrips3D.columns(strips=[np.zeros((2, 3))]))
_STRIP_POINT = _L3D_TYPES["strips"].value_type.value_type  # a strip's point: 3 float32


def _offsets(n: int, per_row: int = 1) -> pa.Array:
    """List offsets of ``n`` rows of ``per_row`` values each."""
    return pa.array(np.arange(0, n * per_row + 1, per_row, dtype=np.int32))


def _vec_list(values: np.ndarray, list_type: pa.DataType, per_row: int = 1) -> pa.Array:
    """Fixed-size float32 vectors, ``per_row`` to a row, as a column of ``list_type``."""
    flat = pa.array(np.ascontiguousarray(values, np.float32).reshape(-1))
    inner = pa.FixedSizeListArray.from_arrays(flat, type=list_type.value_type)
    return pa.ListArray.from_arrays(_offsets(len(values) // per_row, per_row), inner,
                                    type=list_type)


def _string_list(values: list[str], list_type: pa.DataType) -> pa.Array:
    """A list-of-one-string column of ``list_type`` (child and parent frame names)."""
    return pa.ListArray.from_arrays(_offsets(len(values)), pa.array(values, pa.string()),
                                    type=list_type)


def _legs_column(legs: list[np.ndarray]) -> _Column:
    """One row per frame of two strips (left, right leg) of ``len(LEG_CHAIN) + 1`` points."""
    pts = np.concatenate([pair.reshape(-1, 3) for pair in legs]).astype(np.float32)
    inner = pa.FixedSizeListArray.from_arrays(pa.array(pts.reshape(-1)), type=_STRIP_POINT)
    strips = pa.ListArray.from_arrays(_offsets(2 * len(legs), len(LEG_CHAIN) + 1), inner,
                                      type=_L3D_TYPES["strips"].value_type)
    rows = pa.ListArray.from_arrays(_offsets(len(legs), 2), strips, type=_L3D_TYPES["strips"])
    return _Column(_L3D["strips"], rows)


class Batcher:
    """Converts batches of raw messages to Rerun columns and sends them on ``rec``."""

    def __init__(
        self,
        rec: rr.RecordingStream,
        channels: Channels,
        skeleton: Skeleton | None = None,
        robot_hz: float = 30.0,
        map_hz: float = 10.0,
        points_per_s: float = 240.0,
        scalar_flush_s: float = 0.25,
        table_size: int = 8192,
    ) -> None:
        self.rec = rec
        self.ch = channels
        self.skeleton = skeleton
        #: rows per send -> the body-frame name columns (``_send_body_frames``)
        self._frame_columns: dict[int, tuple[_Column, _Column]] = {}
        self.robot_period_us = int(1e6 / robot_hz)
        self.map_period_s = 1.0 / map_hz
        self.points_per_s = points_per_s
        self.scalar_flush_s = scalar_flush_s
        self._last_flush_s = time.monotonic()
        self._series_named: set[str] = set()
        self._pinhole: tuple[float, ...] | None = None
        self.wall_offset_ns = time.time_ns() - time.monotonic_ns()
        self.sim_us = 0  # newest sim time seen on a state channel
        self.t_state = KeyTable(table_size)  # utime -> send time
        self.t_net = KeyTable(table_size)
        self.t_depth = KeyTable(256)
        self.t_map_mono = KeyTable(256)  # map seq -> send time
        self.t_map_utime = KeyTable(256)  # map seq -> utime
        self.rejected: dict[str, int] = {}
        self.errors: dict[str, int] = {}
        self.batches = 0
        self._batch_ms_max = 0.0
        self.last_batch_ms = 0.0
        self._last_robot_us = -(1 << 62)
        self._last_estimate_us = -(1 << 62)
        self._gt_seen_ns = 0
        self._last_map_s = 0.0
        #: loop -> (wall ns, ticks_total) of its recent TIMING reports (``_rate``)
        self._rate_hist: dict[str, deque[tuple[int, int]]] = {}
        self._last_footholds_s = 0.0
        self._grid: tuple[np.ndarray, float, tuple[int, int], np.ndarray] | None = None
        self._map_has_mask = False
        self._states: dict[str, str] = {}
        self._scalars: dict[str, list[tuple[np.ndarray, np.ndarray, np.ndarray]]] = {}
        self._handlers: list[tuple[str, Callable[[list[bytes]], None]]] = [
            # sources before destinations, so a hop within one batch is matched
            (channels.state, self._on_state),
            (channels.network_state, self._on_network_state),
            (channels.ground_truth, self._on_ground_truth),
            (channels.depth, self._on_depth),
            (channels.elevation_map, self._on_map),
            (channels.torque, self._on_torque),
            (channels.applied_input, self._on_applied_input),
            (channels.plan, self._on_plan),
            (channels.footholds, self._on_footholds),
            (channels.mpfc_debug, self._on_mpfc_debug),
            (channels.osc_debug, self._on_osc_debug),
            (channels.timing, self._on_timing),
            (channels.supervisor_status, self._on_supervisor),
        ]

    # -- the batch ---------------------------------------------------------------------------
    def process(
        self,
        batch: dict[str, list[bytes]],
        stats: dict[str, ChannelStats] | None = None,
        flush: bool = False,
    ) -> None:
        """Convert and send one batch (channel -> raw messages, oldest first); the queued
        scalar series too when ``scalar_flush_s`` has passed or ``flush`` is set."""
        t0 = time.perf_counter()
        for channel, handler in self._handlers:
            msgs = batch.get(channel)
            if not msgs:
                continue
            try:
                handler(msgs)
            except Exception as exc:  # one bad channel must not stop the others
                n = self.errors.get(channel, 0) + 1
                self.errors[channel] = n
                if n in (1, 10, 100) or n % 1000 == 0:
                    log.warning("%s: could not convert a batch (%s; %d so far)", channel, exc, n)
        self.batches += 1
        now = time.monotonic()
        span = now - self._last_flush_s
        if flush or span >= self.scalar_flush_s:
            self._last_flush_s = now
            if stats is not None:
                self._health(stats)
            self._flush_scalars()
        self.last_batch_ms = (time.perf_counter() - t0) * 1e3
        # reported at the next flush (so a flushing batch counts its own flush too)
        self._batch_ms_max = max(self._batch_ms_max, self.last_batch_ms)

    # -- helpers -----------------------------------------------------------------------------
    def _times(self, h: Headers) -> tuple[np.ndarray, np.ndarray]:
        """(sim_us, wall_ns) of the rows of ``h`` (see the module docstring)."""
        sim = np.where(h.utime > 0, h.utime, self.sim_us)
        now = time.time_ns()
        wall = h.mono_ns + self.wall_offset_ns
        # unstamped, or stamped by another host's monotonic clock: use the arrival batch's time
        return sim, np.where(np.abs(wall - now) < 60_000_000_000, wall, now)

    def _headers(self, channel: str, msgs: Sequence[bytes], msg_type: type,
                 lead: struct.Struct | None = None) -> Headers:
        h = read_headers(msgs, _FP[msg_type], lead)
        if h.rejected:
            self.rejected[channel] = self.rejected.get(channel, 0) + h.rejected
        return h

    def _advance_clock(self, h: Headers) -> None:
        """Follow sim time forward, and back when the sim restarts (a jump back over 5 s)."""
        if not len(h) or h.utime[-1] <= 0:
            return
        newest = int(h.utime[-1])
        self.sim_us = newest if newest < self.sim_us - 5_000_000 else max(self.sim_us, newest)

    def _indexes(self, sim_us: Any, wall_ns: Any) -> list[_Times]:
        """The two timelines of a send."""
        return [
            _Times("sim_time", np.asarray(sim_us, np.int64).astype("timedelta64[us]")),
            _Times("wall_time", np.asarray(wall_ns, np.int64).astype("datetime64[ns]")),
        ]

    def send(self, path: str, sim_us: Any, wall_ns: Any, columns: Any) -> None:
        """One ``send_columns`` call for ``path``."""
        self.send_at(path, self._indexes(sim_us, wall_ns), columns)

    def send_at(self, path: str, indexes: list[_Times], columns: Any) -> None:
        """One ``send_columns`` call for ``path`` on prebuilt time columns (the robot's four
        entities share theirs: building them costs ~20 us a send)."""
        rr.send_columns(path, indexes=indexes, columns=columns, recording=self.rec)

    def scalar(self, path: str, sim_us: np.ndarray, wall_ns: np.ndarray, values: Any) -> None:
        """Queue scalar rows for ``path``; sent (reduced) at the next flush."""
        vals = np.asarray(values, dtype=np.float64)
        if len(vals):
            self._scalars.setdefault(path, []).append(
                (np.asarray(sim_us, np.int64), np.asarray(wall_ns, np.int64), vals)
            )

    def series(self, path: str, sim_us: np.ndarray, wall_ns: np.ndarray, rows: Any,
               names: Sequence[str]) -> None:
        """Queue rows of ``len(names)`` values each, one plotted line per name."""
        if path not in self._series_named:  # once per entity, so not per message
            self._series_named.add(path)
            self.rec.log(path, rr.SeriesLines(names=list(names)), static=True)
        vals = np.asarray(rows, dtype=np.float64).reshape(-1, len(names))
        if len(vals):
            self._scalars.setdefault(path, []).append(
                (np.asarray(sim_us, np.int64), np.asarray(wall_ns, np.int64), vals)
            )

    def _flush_scalars(self) -> None:
        bucket_ns = int(1e9 / self.points_per_s)
        for path, parts in self._scalars.items():
            sim = np.concatenate([p[0] for p in parts])
            wall = np.concatenate([p[1] for p in parts])
            vals = np.concatenate([p[2] for p in parts])
            sim, wall, vals = reduce_max(sim, wall, vals, bucket_ns)
            cols = rr.Scalars.columns(scalars=vals.reshape(-1))
            if vals.ndim == 2:
                cols = cols.partition([vals.shape[1]] * len(vals))
            self.send(path, sim, wall, cols)
        self._scalars.clear()

    def _state_change(self, path: str, sim_us: int, wall_ns: int, state: str,
                      rows: list[tuple[str, int, int, str]]) -> None:
        """Append a lane row to ``rows`` only when ``path``'s state changed."""
        if self._states.get(path) != state:
            self._states[path] = state
            rows.append((path, sim_us, wall_ns, state))

    def _send_states(self, rows: list[tuple[str, int, int, str]]) -> None:
        """One StateChange send per lane."""
        by_path: dict[str, list[tuple[int, int, str]]] = {}
        for path, s, w, st in rows:
            by_path.setdefault(path, []).append((s, w, st))
        for path, items in by_path.items():
            self.send(
                path,
                [i[0] for i in items],
                [i[1] for i in items],
                rr.StateChange.columns(state=[i[2] for i in items]),
            )

    def _hop(self, name: str, table: KeyTable, keys: np.ndarray, h: Headers,
             sim: np.ndarray, wall: np.ndarray) -> np.ndarray:
        """Queue ``latency/<name>_ms`` for the rows of ``h`` whose key is in ``table``."""
        found, lat = hop_latency_ms(table, keys, h.mono_ns)
        self.scalar(f"latency/{name}_ms", sim[found], wall[found], lat)
        return found

    # -- robot -------------------------------------------------------------------------------
    def _send_robot(self, sim: np.ndarray, wall: np.ndarray, qs: list[np.ndarray],
                    feet: list[np.ndarray] | None) -> None:
        """Pelvis pose, the meshed bodies' poses (when the meshes are loaded), the leg chains
        (with the model) and feet, one row per q."""
        q = np.stack(qs)
        at = self._indexes(sim, wall)
        self.send_at("world/robot/pelvis", at, [
            _Column(_T3D["translation"], _vec_list(q[:, 0:3], _T3D_TYPES["translation"])),
            _Column(_T3D["quaternion"], _vec_list(q[:, [4, 5, 6, 3]], _T3D_TYPES["quaternion"])),
        ])
        sk = self.skeleton
        legs: list[np.ndarray] = []
        if sk is not None and q.shape[1] == sk.nq:
            poses = [sk.pose(qi) for qi in q]
            legs = [p.legs for p in poses]
            if sk.has_meshes:
                self._send_body_frames(sim, wall, poses)
            # the leg chains too (one send; hidden in the 3D view when the meshes are drawn)
            self.send_at("world/robot/legs", at, [_legs_column(legs)])
        if feet is None and legs:
            feet = [pair[:, -1, :] for pair in legs]
        if feet:
            self.send_at("world/robot/feet", at, [_Column(
                _P3D["positions"], _vec_list(np.concatenate(feet), _P3D_TYPES["positions"], 2))])

    def _send_body_frames(self, sim: np.ndarray, wall: np.ndarray, poses: list[Pose]) -> None:
        """Every meshed body's world pose, one Transform3D row per body and frame, in one
        send: each row names the body's frame (the static meshes live in it)."""
        sk = self.skeleton
        assert sk is not None
        nb = len(sk.frames)
        n = len(poses) * nb
        frames = self._frame_columns.get(n)
        if frames is None:  # the same strings every frame: built once per batch size
            frames = (
                _Column(_T3D["child_frame"],
                        _string_list(sk.frames * len(poses), _T3D_TYPES["child_frame"])),
                _Column(_T3D["parent_frame"],
                        _string_list([WORLD_FRAME] * n, _T3D_TYPES["parent_frame"])),
            )
            self._frame_columns[n] = frames
        pos = np.concatenate([p.body_pos for p in poses])
        quat = np.concatenate([p.body_quat for p in poses])
        self.send_at(FRAMES_ENTITY, self._indexes(np.repeat(sim, nb), np.repeat(wall, nb)), [
            _Column(_T3D["translation"], _vec_list(pos, _T3D_TYPES["translation"])),
            _Column(_T3D["quaternion"], _vec_list(quat, _T3D_TYPES["quaternion"])),
            *frames,
        ])

    def _on_state(self, msgs: list[bytes]) -> None:
        """CASSIE_STATE: hop source; the robot when there is no ground truth, else the
        estimated pelvis beside it."""
        h = self._headers(self.ch.state, msgs, robot_state_t)
        self._advance_clock(h)
        self.t_state.add(h.utime, h.mono_ns)
        sim, wall = self._times(h)
        gt_recent = time.monotonic_ns() - self._gt_seen_ns < 1_000_000_000
        last = self._last_estimate_us if gt_recent else self._last_robot_us
        picks, last = pick_by_period(h.utime, self.robot_period_us, last, cap=4)
        if not picks:
            return
        states = [robot_state_t.decode(msgs[int(h.index[i])]) for i in picks]
        qs = [np.asarray(s.q, np.float64) for s in states]
        qs_ok = [i for i, qq in enumerate(qs) if len(qq) >= 7]
        if not qs_ok:
            return
        ps, pw = sim[picks][qs_ok], wall[picks][qs_ok]
        if gt_recent:
            self._last_estimate_us = last
            pos = np.stack([qs[i][0:3] for i in qs_ok])
            self.send("world/estimate/pelvis", ps, pw, rr.Points3D.columns(positions=pos))
        else:
            self._last_robot_us = last
            self._send_robot(ps, pw, [qs[i] for i in qs_ok], None)

    def _on_ground_truth(self, msgs: list[bytes]) -> None:
        """GROUND_TRUTH: the robot, at ``robot_hz`` of sim time."""
        h = self._headers(self.ch.ground_truth, msgs, ground_truth_t)
        if not len(h):
            return
        self._advance_clock(h)
        self._gt_seen_ns = time.monotonic_ns()
        sim, wall = self._times(h)
        picks, self._last_robot_us = pick_by_period(
            h.utime, self.robot_period_us, self._last_robot_us, cap=4
        )
        if not picks:
            return
        gts = [ground_truth_t.decode(msgs[int(h.index[i])]) for i in picks]
        ok = [i for i, g in enumerate(gts) if len(g.q) >= 7]
        if not ok:
            return
        feet = [np.asarray(gts[i].foot_pos, np.float64).reshape(2, 3) for i in ok]
        self._send_robot(
            sim[picks][ok], wall[picks][ok], [np.asarray(gts[i].q, np.float64) for i in ok], feet
        )

    # -- control hops ------------------------------------------------------------------------
    def _on_network_state(self, msgs: list[bytes]) -> None:
        """NETWORK_CASSIE_STATE: source of the state -> plan hop."""
        h = self._headers(self.ch.network_state, msgs, robot_state_t)
        self._advance_clock(h)
        self.t_net.add(h.utime, h.mono_ns)

    def _on_torque(self, msgs: list[bytes]) -> None:
        """OSC_TORQUE: the state -> torque hop."""
        h = self._headers(self.ch.torque, msgs, torque_command_t)
        sim, wall = self._times(h)
        self._hop("state_to_torque", self.t_state, h.utime, h, sim, wall)

    def _on_applied_input(self, msgs: list[bytes]) -> None:
        """CASSIE_INPUT: the sensor packet (state) -> torque applied hop."""
        h = self._headers(self.ch.applied_input, msgs, applied_input_t)
        sim, wall = self._times(h)
        self._hop("sensor_to_applied", self.t_state, h.utime, h, sim, wall)

    def _on_plan(self, msgs: list[bytes]) -> None:
        """NETWORK_MPFC_PLAN: the state -> plan hop, gait lanes, the newest plan in 3D."""
        h = self._headers(self.ch.plan, msgs, mpfc_output_t, _PLAN_LEAD)
        if not len(h):
            return
        sim, wall = self._times(h)
        self._hop("state_to_plan", self.t_net, h.utime, h, sim, wall)
        states: list[tuple[str, int, int, str]] = []
        for i, g in enumerate(h.fields[:, 0].astype(int).tolist()):
            self._state_change(
                "mpfc/gait", int(sim[i]), int(wall[i]), _GAIT.get(g, f"gait {g}"), states
            )
        self._send_states(states)
        p = mpfc_output_t.decode(msgs[int(h.index[-1])])  # draw the newest plan of the batch
        s, w = sim[-1:], wall[-1:]
        steps = np.asarray(p.footsteps_world, np.float64).reshape(-1, 3)
        if len(steps):
            self.send("world/plan/footsteps", s, w,
                      rr.Points3D.columns(positions=steps).partition([len(steps)]))
        self.send("world/plan/next_footstep", s, w,
                  rr.Points3D.columns(positions=np.asarray([p.next_footstep_world])))
        self.send("world/plan/stance_foot", s, w,
                  rr.Points3D.columns(positions=np.asarray([p.stance_foot_world])))

    # -- perception --------------------------------------------------------------------------
    def _on_depth(self, msgs: list[bytes]) -> None:
        """DEPTH (headers only): hop source and the camera pose."""
        h = self._headers(self.ch.depth, msgs, depth_frame_t, _DEPTH_LEAD)
        if not len(h):
            return
        self.t_depth.add(h.utime, h.mono_ns)
        sim, wall = self._times(h)
        f = h.fields[-1]
        s, w = sim[-1:], wall[-1:]
        quat = f[10:14]  # w, x, y, z
        self.send(
            "world/camera",
            s,
            w,
            rr.Transform3D.columns(translation=f[None, 7:10], quaternion=quat[None, [1, 2, 3, 0]]),
        )
        intrinsics = tuple(float(x) for x in f[0:6])
        if intrinsics == self._pinhole:
            return
        self._pinhole = intrinsics
        k = np.array([[f[2], 0.0, f[4]], [0.0, f[3], f[5]], [0.0, 0.0, 1.0]])
        self.send(
            "world/camera",
            s,
            w,
            rr.Pinhole.columns(image_from_camera=k[None], resolution=f[None, 0:2]),
        )

    def _on_map(self, msgs: list[bytes]) -> None:
        """ELEVATION_MAP: the depth -> map hop; the newest map drawn at ``map_hz``."""
        h = self._headers(self.ch.elevation_map, msgs, elevation_map_t, _MAP_LEAD)
        if not len(h):
            return
        sim, wall = self._times(h)
        self._hop("depth_to_map", self.t_depth, h.utime, h, sim, wall)
        self.t_map_mono.add(h.seq, h.mono_ns)
        self.t_map_utime.add(h.seq, h.utime)
        now = time.monotonic()
        if now - self._last_map_s < self.map_period_s:
            return
        self._last_map_s = now
        m = elevation_map_t.decode(msgs[int(h.index[-1])])
        self._draw_map(m, sim[-1:], wall[-1:])

    def _draw_map(self, m: Any, sim: np.ndarray, wall: np.ndarray) -> None:
        """Elevation image, 3D cells and (from a mask layer, if any) the S3 mask."""
        layers = elevation_map_from_msg(m)  # (the one codec: runtime.codecs)
        if isinstance(layers, str):
            raise ValueError(layers)
        rows, cols = int(m.rows), int(m.cols)
        elev = layers.get("elevation", next(iter(layers.values())))
        origin = np.asarray(m.origin, np.float64)
        res = float(m.resolution)
        self._grid = (origin, res, (rows, cols), elev)
        finite = np.isfinite(elev)
        lo, hi = (float(elev[finite].min()), float(elev[finite].max())) if finite.any() else (0, 1)
        rgb = colorize(elev, lo, hi)
        # Image rows run down the screen: flip so that +y (world) is up and +x is right.
        self._send_image("maps/elevation", sim, wall, rgb[::-1])
        ii, jj = np.nonzero(finite)
        pts = np.column_stack([origin[0] + jj * res, origin[1] + ii * res, elev[ii, jj]])
        if len(pts):
            self.send(
                "world/elevation_map",
                sim,
                wall,
                rr.Points3D.columns(
                    positions=pts, colors=rgb[ii, jj], radii=np.full(len(pts), 0.5 * res)
                ).partition([len(pts)]),
            )
        mask_name = next((x for x in MASK_LAYERS if x in layers), None)
        self._map_has_mask = mask_name is not None
        if mask_name is not None:
            layer = layers[mask_name]
            mask = np.where(layer > 0.5, MASK_SAFE, MASK_UNSAFE).astype(np.uint8)
            mask[~np.isfinite(layer) | ~finite] = MASK_UNKNOWN
            self._send_mask(sim, wall, mask)

    def _send_image(self, path: str, sim: np.ndarray, wall: np.ndarray, rgb: np.ndarray) -> None:
        """One RGB image row."""
        h, w = rgb.shape[:2]
        fmt = rr.components.ImageFormat(width=w, height=h, color_model="RGB", channel_datatype="U8")
        self.send(path, sim, wall,
                  rr.Image.columns(buffer=np.ascontiguousarray(rgb).reshape(1, -1), format=[fmt]))

    def _send_mask(self, sim: np.ndarray, wall: np.ndarray, mask: np.ndarray) -> None:
        """One S3 mask row (class ids, flipped like the elevation image)."""
        h, w = mask.shape
        fmt = rr.components.ImageFormat(width=w, height=h, channel_datatype="U8")
        buf = np.ascontiguousarray(mask[::-1]).reshape(1, -1)
        self.send("maps/s3_mask", sim, wall,
                  rr.SegmentationImage.columns(buffer=buf, format=[fmt]))

    def _on_footholds(self, msgs: list[bytes]) -> None:
        """FOOTHOLDS: map -> footholds and depth -> footholds hops; polygons at ``map_hz``
        (and the mask rasterised from them when the map carries none)."""
        h = self._headers(self.ch.footholds, msgs, foothold_set_t, _FOOTHOLDS_LEAD)
        if not len(h):
            return
        sim, wall = self._times(h)
        map_seq = h.fields[:, 0].astype(np.int64)
        self._hop("map_to_footholds", self.t_map_mono, map_seq, h, sim, wall)
        # depth -> footholds: by utime when S3 keeps the frame's utime, else through the map
        found, src = self.t_depth.lookup(h.utime)
        via_map, map_utime = self.t_map_utime.lookup(map_seq)
        found2, src2 = self.t_depth.lookup(map_utime)
        src = np.where(found, src, src2)
        ok = found | (via_map & found2)
        lat = (h.mono_ns[ok] - src[ok]).astype(np.float64) * 1e-6
        self.scalar("latency/depth_to_footholds_ms", sim[ok], wall[ok], lat)
        now = time.monotonic()
        if now - self._last_footholds_s < self.map_period_s:
            return
        self._last_footholds_s = now
        fs = foothold_set_t.decode(msgs[int(h.index[-1])])
        s, w = sim[-1:], wall[-1:]
        polys = [np.asarray(f.vertices, np.float64).reshape(-1, 3) for f in fs.footholds]
        polys = [p for p in polys if len(p) >= 2]
        strips = [np.vstack([p, p[:1]]) for p in polys]
        self.send("world/footholds", s, w,
                  rr.LineStrips3D.columns(strips=strips).partition([len(strips)]))
        self.scalar("perception/num_footholds", s, w, [len(polys)])
        if not self._map_has_mask and self._grid is not None:
            origin, res, shape, elev = self._grid
            inside = polygon_mask(polys, origin, res, shape)
            mask = np.where(inside, MASK_SAFE, MASK_UNSAFE).astype(np.uint8)
            mask[~np.isfinite(elev)] = MASK_UNKNOWN
            self._send_mask(s, w, mask)

    # -- debug and timing --------------------------------------------------------------------
    def _on_mpfc_debug(self, msgs: list[bytes]) -> None:
        """MPFC_DEBUG: solve and optimizer times, nodes explored (leading fields only)."""
        h = self._headers(self.ch.mpfc_debug, msgs, mpfc_debug_t, _MPFC_DEBUG_LEAD)
        sim, wall = self._times(h)
        self.scalar("mpfc/solve_ms", sim, wall, h.fields[:, 0])
        self.scalar("mpfc/optimizer_ms", sim, wall, h.fields[:, 1])
        self.scalar("mpfc/nodes_explored", sim, wall, h.fields[:, 2])

    def _on_osc_debug(self, msgs: list[bytes]) -> None:
        """OSC_DEBUG: tick and QP solve times (leading fields only)."""
        h = self._headers(self.ch.osc_debug, msgs, osc_debug_t, _OSC_DEBUG_LEAD)
        sim, wall = self._times(h)
        self.scalar("osc/tick_ms", sim, wall, h.fields[:, 0])
        self.scalar("osc/solve_ms", sim, wall, h.fields[:, 1])

    def _rate(self, name: str, wall_ns: int, t: loop_timing_t) -> float:
        """A loop's rate over the last ~RATE_WINDOW_S of its reports (ticks_total over the
        time between them), not one 0.1 s window's: a 15-30 Hz loop has 0-4 ticks in one, and
        61 % of the perception/S3 rate samples read 0 Hz."""
        hist = self._rate_hist.setdefault(name, deque())
        hist.append((int(wall_ns), int(t.ticks_total)))
        while len(hist) > 2 and hist[-1][0] - hist[1][0] >= RATE_WINDOW_S * 1e9:
            hist.popleft()
        (t0, n0), (t1, n1) = hist[0], hist[-1]
        if t1 - t0 < 0.2e9:  # too short a span yet: the report's own figure
            return float(t.rate_hz)
        return (n1 - n0) / ((t1 - t0) * 1e-9)

    def _on_timing(self, msgs: list[bytes]) -> None:
        """TIMING: rate, execution time, lateness and deadline misses per loop."""
        h = self._headers(self.ch.timing, msgs, loop_timing_t)
        sim, wall = self._times(h)
        for row in range(len(h)):
            t = loop_timing_t.decode(msgs[int(h.index[row])])
            name = f"{esc(t.process)}/{esc(t.loop)}"
            s, w = sim[row : row + 1], wall[row : row + 1]
            self.scalar(f"timing/rate_hz/{name}", s, w, [self._rate(name, w[0], t)])
            label = f"{t.process}/{t.loop}"
            exec_ms, names = [t.exec_p50_ms, t.exec_p99_ms, t.exec_max_ms], _stat_names(label)
            if t.deadline_ms > 0:  # drawn beside them: what the tail is measured against
                exec_ms, names = [*exec_ms, t.deadline_ms], [*names, f"{label} deadline"]
            self.series(f"timing/exec_ms/{name}", s, w, exec_ms, names)
            self.series(f"timing/lateness_ms/{name}", s, w,
                        [t.lateness_p50_ms, t.lateness_p99_ms, t.lateness_max_ms],
                        _stat_names(label))
            self.scalar(f"timing/deadline_misses/{name}", s, w, [t.deadline_misses])

    def _on_supervisor(self, msgs: list[bytes]) -> None:
        """SUPERVISOR_STATUS: stack and process states as lanes (on change), CPU use."""
        h = self._headers(self.ch.supervisor_status, msgs, supervisor_status_t)
        sim, wall = self._times(h)
        states: list[tuple[str, int, int, str]] = []
        for row in range(len(h)):
            st = supervisor_status_t.decode(msgs[int(h.index[row])])
            s, w = int(sim[row]), int(wall[row])
            self._state_change("supervisor/states/_stack", s, w, st.state, states)
            for p in st.processes:
                self._state_change(f"supervisor/states/{esc(p.name)}", s, w, p.state, states)
                self.scalar(f"supervisor/cpu_percent/{esc(p.name)}", sim[row : row + 1],
                            wall[row : row + 1], [p.cpu_percent])
        self._send_states(states)

    def _health(self, stats: dict[str, ChannelStats]) -> None:
        """The dashboard's own load: dropped messages (own backlog), slowest batch since the
        last flush (ms)."""
        s = np.array([self.sim_us], np.int64)
        w = np.array([time.time_ns()], np.int64)
        cols: dict[str, float] = {
            "dashboard/dropped_total": sum(st.dropped for st in stats.values()),
            "dashboard/received_total": sum(st.received for st in stats.values()),
            "dashboard/batch_ms_max": self._batch_ms_max,
            "dashboard/rejected_total": sum(self.rejected.values()),
        }
        for ch, st in stats.items():
            if st.dropped:
                cols[f"dashboard/dropped/{esc(ch)}"] = st.dropped
        for path, v in cols.items():
            self.scalar(path, s, w, [float(v)])
        self._batch_ms_max = 0.0


def _stat_names(label: str) -> list[str]:
    return [f"{label} p50", f"{label} p99", f"{label} max"]


_GAIT = {0: "left stance", 1: "right stance", 2: "double (after left)",
         3: "double (after right)", 4: "standing"}
