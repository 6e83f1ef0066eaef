"""The dashboard's default Rerun layout: robot and maps on the left, timing on the right.

Every view is rooted at an entity subtree written by ``tools.dashboard.convert``, so the
layout and the data agree by construction (``ENTITY_ROOTS`` lists them for tests and docs).
"""

from __future__ import annotations

import rerun as rr
import rerun.blueprint as rrb

#: The entity subtrees the views show, and what each holds.
ENTITY_ROOTS = {
    "world": "3D: robot (pelvis pose, leg skeleton, feet), terrain boxes, elevation map, "
    "foothold polygons, planned footsteps, camera",
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


def _recent(seconds: float) -> list[rr.VisibleTimeRange]:
    """A sliding window of the last ``seconds`` on both timelines (for live viewing)."""
    start = rr.TimeRangeBoundary.cursor_relative(seconds=-seconds)
    end = rr.TimeRangeBoundary.cursor_relative()
    return [
        rr.VisibleTimeRange(timeline, start=start, end=end)
        for timeline in ("sim_time", "wall_time")
    ]


def build_blueprint(window_s: float = 20.0,
                    loops: list[tuple[str, str, float | None]] | None = None) -> rrb.Blueprint:
    """The default layout; time series show the last ``window_s`` seconds before the cursor.
    ``loops`` (process, loop, deadline ms): one execution-time panel per loop as well, its
    deadline drawn and its y-range fixed to twice the deadline, so a start-up spike of
    ~200 ms does not flatten a 2 kHz loop's 0.1 ms to a line at zero."""
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

    left = rrb.Vertical(
        rrb.Spatial3DView(origin="world", name="Robot, terrain, footholds and plan"),
        rrb.Horizontal(
            rrb.Spatial2DView(origin="maps/elevation", name="Elevation map"),
            rrb.Spatial2DView(origin="maps/s3_mask", name="S3 mask"),
        ),
        row_shares=[2.0, 1.0],
    )
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
    right = rrb.Vertical(timing, lanes, row_shares=[3.0, 1.0])
    return rrb.Blueprint(
        rrb.Horizontal(left, right, column_shares=[2.0, 3.0]),
        rrb.TimePanel(timeline="sim_time"),
        collapse_panels=False,
    )


def log_static(rec: rr.RecordingStream) -> None:
    """Static, once-per-recording data: mask classes and the pelvis axes."""
    rec.log(
        "maps/s3_mask",
        rr.AnnotationContext(
            [(0, "unsafe", (200, 60, 60)), (1, "safe", (60, 190, 80)), (2, "unknown", (70, 70, 70))]
        ),
        static=True,
    )
    rec.log("world/robot/pelvis", rr.TransformAxes3D(0.25), static=True)
    rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
