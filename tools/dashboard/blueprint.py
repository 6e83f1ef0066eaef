"""The dashboard's default Rerun layout: robot and maps on the left, timing on the right.

Every view is rooted at an entity subtree written by ``tools.dashboard.convert``, so the
layout and the data agree by construction (``ENTITY_ROOTS`` lists them for tests and docs).
"""

from __future__ import annotations

import math

import rerun as rr
import rerun.blueprint as rrb

#: The entity subtrees the views show, and what each holds.
ENTITY_ROOTS = {
    "world": "3D: robot (the model's meshes at its joint angles, else the leg skeleton; "
    "pelvis pose, feet), terrain boxes, elevation map, foothold polygons, planned footsteps, "
    "camera; the eye follows the pelvis",
    "maps/elevation": "the elevation map, top-down, coloured by height (+x right, +y up)",
    "maps/s3_mask": "the S3 safe-terrain mask (green safe, red unsafe, grey unknown)",
    "timing/rate_hz": "loop rate of each process/loop (TIMING)",
    "timing/exec_ms": "execution time p50/p99/max per loop, and its deadline",
    "timing/lateness_ms": "lateness p50/p99/max per loop",
    "timing/deadline_misses": "deadline misses per reporting window per loop",
    "latency": "latency of each hop, from header send times matched by utime",
    "mpfc": "MPFC solve time, optimizer time, nodes explored; gait state lanes",
    "osc": "OSC tick and QP solve time",
    "supervisor/states": "supervisor state and each process's state as lanes over time",
    "dashboard": "the dashboard's own load: dropped messages, batch time",
}

#: The leg chains as lines (left out of the 3D view when the meshes are drawn).
LEGS_ENTITY = "world/robot/legs"
#: The entity the 3D view's eye follows: two static points in the pelvis's frame, symmetric
#: about it, so that it moves with every robot frame. The viewer centres a tracked entity's
#: bounding box and, when tracking starts on an entity with data, puts the eye 1.5 times its
#: bounding radius away: the pelvis's own 0.25 m axes would put it 0.3 m from the robot.
TRACKED_ENTITY = "world/robot/pelvis/eye_extent"
#: Half the extent of those points (m): the eye starts 1.5 * |EYE_EXTENT| (about 4.2 m) away.
EYE_EXTENT = (1.6, 1.6, 1.6)
#: Where the eye starts, and what it looks at, in world coordinates (m): beside the robot's
#: start (the pelvis at about (0, 0, 1)), a little ahead and above it, at that same distance
#: (a viewer that starts before the first robot frame keeps this one), so that the walk (+x)
#: crosses the view; tracking then carries the view along with the pelvis.
EYE_LOOK_AT = (0.0, 0.0, 1.0)
_EYE_DIRECTION = (1.2, -3.2, 0.9)  # from the look target: to the right of the walk, ahead, up
_EYE_DISTANCE = 1.5 * math.sqrt(sum(e * e for e in EYE_EXTENT))
EYE_START = tuple(
    t + d * _EYE_DISTANCE / math.sqrt(sum(x * x for x in _EYE_DIRECTION))
    for t, d in zip(EYE_LOOK_AT, _EYE_DIRECTION, strict=True)
)


def robot_eye() -> rrb.EyeControls3D:
    """The 3D view's eye: an orbit camera that tracks the pelvis (drag to orbit around it,
    scroll to zoom; it keeps following)."""
    return rrb.EyeControls3D(
        kind=rrb.Eye3DKind.Orbital,
        position=EYE_START,
        look_target=EYE_LOOK_AT,
        eye_up=(0.0, 0.0, 1.0),
        tracking_entity=TRACKED_ENTITY,
    )


def _recent(seconds: float) -> list[rr.VisibleTimeRange]:
    """A sliding window of the last ``seconds`` on both timelines (for live viewing)."""
    start = rr.TimeRangeBoundary.cursor_relative(seconds=-seconds)
    end = rr.TimeRangeBoundary.cursor_relative()
    return [
        rr.VisibleTimeRange(timeline, start=start, end=end)
        for timeline in ("sim_time", "wall_time")
    ]


def robot_view(robot_meshes: bool = False) -> rrb.Spatial3DView:
    """The 3D view of everything under ``world``, its eye tracking the pelvis. With
    ``robot_meshes`` the robot is drawn from its meshes, so the view leaves the stick skeleton
    out (it is still recorded, and can be added back in the viewer)."""
    return rrb.Spatial3DView(
        origin="world",
        name="Robot, terrain, footholds and plan",
        contents=["$origin/**", f"- /{LEGS_ENTITY}"] if robot_meshes else "$origin/**",
        eye_controls=robot_eye(),
    )


def timing_views(window_s: float = 20.0,
                 loops: list[tuple[str, str, float | None]] | None = None
                 ) -> tuple[rrb.Tabs | rrb.Grid, rrb.StateTimelineView]:
    """The timing panels (all loops together, and one per loop when ``loops`` are given) and
    the supervisor's state lanes; time series show the last ``window_s`` seconds before the
    cursor."""
    recent = _recent(window_s)

    def series(origin: str, name: str, contents: str | list[str] = "$origin/**",
               y_max: float | None = None) -> rrb.TimeSeriesView:
        axis = rrb.ScalarAxis(range=(0.0, y_max), zoom_lock=False) if y_max else None
        return rrb.TimeSeriesView(origin=origin, contents=contents, name=name, time_ranges=recent,
                                  axis_y=axis)

    per_loop = [  # (a process's loops together: its loop's name is its node's)
        series(f"timing/exec_ms/{rr.escape_entity_path_part(p)}", f"{p} execution (ms)",
               y_max=2.0 * d if d else None)
        for p, d in dict((p, d) for p, _, d in (loops or [])).items()
    ]
    overview = rrb.Grid(
        series("timing/rate_hz", "Loop rate (Hz)"),
        series("timing/exec_ms", "Execution time (ms)"),
        series("timing/lateness_ms", "Lateness (ms)"),
        series("timing/deadline_misses", "Deadline misses per window"),
        series("latency", "Hop latency (ms)"),
        rrb.Tabs(
            series("mpfc", "MPFC solve (ms)", ["$origin/solve_ms", "$origin/optimizer_ms"]),
            series("osc", "OSC tick (ms)"),
            series("dashboard", "Dashboard load"),
        ),
        grid_columns=2,
        name="All loops",
    )
    timing = (rrb.Tabs(overview, rrb.Grid(*per_loop, grid_columns=2, name="Each loop"))
              if per_loop else overview)
    lanes = rrb.StateTimelineView(
        origin="/",
        contents=["/supervisor/states/**", "/mpfc/gait"],
        name="Supervisor and gait states",
    )
    return timing, lanes


def build_blueprint(window_s: float = 20.0,
                    loops: list[tuple[str, str, float | None]] | None = None,
                    robot_meshes: bool = False,
                    play_state: str | None = None,
                    collapse_panels: bool = False) -> rrb.Blueprint:
    """The default layout; time series show the last ``window_s`` seconds before the cursor.
    ``loops`` (process, loop, deadline ms): one execution-time panel per loop as well, its
    deadline drawn and its y-range fixed to twice the deadline, so a start-up spike of
    ~200 ms does not flatten a 2 kHz loop's 0.1 ms to a line at zero. ``robot_meshes``: see
    ``robot_view``. ``play_state`` ("following", "paused", "playing"): the time panel's, else
    the viewer's own choice (live it follows the newest data; a recording plays from its
    start). ``collapse_panels``: the viewer's side panels closed (for screenshots)."""
    left = rrb.Vertical(
        robot_view(robot_meshes),
        rrb.Horizontal(
            rrb.Spatial2DView(origin="maps/elevation", name="Elevation map"),
            rrb.Spatial2DView(origin="maps/s3_mask", name="S3 mask"),
        ),
        row_shares=[2.0, 1.0],
    )
    timing, lanes = timing_views(window_s, loops)
    right = rrb.Vertical(timing, lanes, row_shares=[3.0, 1.0])
    return rrb.Blueprint(
        rrb.Horizontal(left, right, column_shares=[2.0, 3.0]),
        rrb.TimePanel(timeline="sim_time", play_state=play_state),
        collapse_panels=collapse_panels,
    )


def log_static(rec: rr.RecordingStream) -> None:
    """Static, once-per-recording data: mask classes, the pelvis axes and the eye's target."""
    rec.log(
        "maps/s3_mask",
        rr.AnnotationContext(
            [(0, "unsafe", (200, 60, 60)), (1, "safe", (60, 190, 80)), (2, "unknown", (70, 70, 70))]
        ),
        static=True,
    )
    rec.log("world/robot/pelvis", rr.TransformAxes3D(0.25), static=True)
    # what the eye tracks (see TRACKED_ENTITY): two points of half a millimetre, a quarter of
    # a pixel at the eye's distance (fully transparent ones are left out of the bounding box
    # the tracking uses)
    ex = EYE_EXTENT
    rec.log(TRACKED_ENTITY, rr.Points3D([[-ex[0], -ex[1], -ex[2]], list(ex)], radii=0.0005),
            static=True)
    rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
