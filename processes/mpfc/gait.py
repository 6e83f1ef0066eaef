"""The MPFC's gait clock and what it keeps of the terrain between solves, with no LCM in it.

The clock times the gait from touchdowns (the paper's Fig. 4): a stance phase starts at each
touchdown with T_ss + T_ds remaining; the solution's stance time is taken only after T_ds
(double stance), and the swing foot's planned touchdown ends the phase. ``within_height``
and ``ReachableFootholds`` leave out footholds no leg reaches, and ``Halt`` stops the gait
where no foothold ahead is within a step (both ours, see processes/mpfc/process.py's
docstring); ``MapHeight`` is the elevation map's height lookup of Section IX-A-3.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numba
import numpy as np

from processes.footstep_search.footholds import WorldFootholds
from runtime.geometry import Foothold

LEFT, RIGHT = 0, 1


class GaitClock:
    """Which foot stands, since when, and when the next touchdown is (Fig. 4).

    Started from standing, the first double stance lasts ``start_ds_s`` instead of T_ds
    (ours): the OSC moves the centre of pressure from the right foot to the left over it, as
    in every double stance (2), and the CoM, centred between feet 27 cm apart, gets over the
    left foot and moving towards it before the right foot lifts. With T_ds (0.1 s) the CoM
    was still 13 cm outside the stance foot at rest when the swing began: it fell outward and
    the first steps carried the robot 0.2 m sideways (measured), off a 23 cm beam."""

    def __init__(self, step_period_s: float, t_ds_s: float = 0.0,
                 start_ds_s: float = 0.0) -> None:
        self.step_period_s = step_period_s  # T_ss + T_ds
        self.start_extra_s = max(start_ds_s - t_ds_s, 0.0)
        self.stance: int | None = None
        self.touchdown_s = 0.0
        self.next_touchdown_s = 0.0
        self.extra_ds_s = 0.0  # this stance's double stance beyond T_ds (the start's)
        self._air_foot: int | None = None  # started mid-step: the foot that was in the air

    def advance(self, t: float, in_contact: Sequence[bool], at_rest: bool = True) -> bool:
        """Move the clock to ``t``; a new stance at the planned touchdown. False while it
        waits to start (a foot in the air: see ``first_stance``). True when it (re)started.
        ``at_rest``: the robot stands still (a start from standing, not a restart mid-walk
        in double stance: only then the start's longer double stance)."""
        if self.stance is None:
            stance = self.first_stance(in_contact)
            if stance is None:
                return False
            # at the first start: as if the left foot just touched down (the gait begins in
            # double stance, where the OSC hands over); restarted mid-walk: the foot that did
            self.stance = stance
            self.touchdown_s = t
            if self._air_foot is None and at_rest:  # from standing: the start's weight shift
                self.extra_ds_s = self.start_extra_s
            self.next_touchdown_s = t + self.step_period_s + self.extra_ds_s
            return True
        if t >= self.next_touchdown_s:  # touchdown of the swing foot: the stances swap
            self.stance = 1 - self.stance
            self.extra_ds_s = 0.0
            self.touchdown_s = self.next_touchdown_s
            self.next_touchdown_s = self.touchdown_s + self.step_period_s
        return False

    def from_standing(self, t: float) -> None:
        """Walk on from standing (a stop the robot came to rest in): this stance begins at
        ``t`` with the start's longer double stance, as the first start from standing does
        (ours). After a stop the OSC stood with the feet 27 cm apart; walking on with T_ds the
        swing began with the CoM 13 cm outside the stance foot, a 24 cm capture step sideways
        followed, and the walk drifted 20 cm off a beam's line (measured with perception).
        The weight shift needs the OSC's hand-over from standing to keep the new stance foot
        loaded (``WalkingController._double_stance``): without it that foot slid 7 cm inward
        in this double stance and every perception beam width fell at 2.8 s (measured)."""
        self.touchdown_s = t
        self.extra_ds_s = self.start_extra_s
        self.next_touchdown_s = t + self.step_period_s + self.extra_ds_s

    def first_stance(self, in_contact: Sequence[bool]) -> int | None:
        """The stance the gait clock starts on, or None to wait for one.

        Started with the robot standing (no foot in the air), it begins as if the left foot
        had just touched down. Started while one foot is in the air -- a restart mid-walk,
        with the OSC stepping on its own meanwhile (``processes.osc.fallback``) -- a clock
        started there would put the stance on a swinging foot: measured live, a restarted
        MPFC then planned 0.9 m steps and Cassie fell. So it waits for that foot's touchdown
        (both feet in contact, from the estimator's contact flags) and starts the clock on
        it; the OSC's own gait touches down on the same foot at the same moment."""
        down = [bool(c) for c in in_contact]
        if sum(down) == 1:  # one foot in the air: remember which, and wait
            self._air_foot = 0 if down[1] else 1
            return None
        if self._air_foot is None:  # the first state, with no foot in the air
            return LEFT
        return self._air_foot if all(down) else None

    def since_touchdown(self, t: float) -> float:
        """Time since the touchdown, less the start's longer double stance while in it."""
        return max(t - self.touchdown_s - self.extra_ds_s, 0.0)

    def remaining(self, t: float) -> float:
        """T*: the nominal time left in this stance (never negative); in the start's longer
        double stance, as at a touchdown (the MPFC plans the stance that follows it)."""
        return max(self.step_period_s - self.since_touchdown(t), 0.0)

    def plan_touchdown(self, t: float, t_remaining_s: float, t_ds_s: float) -> None:
        """A solution's stance time, taken only after double stance (Fig. 4)."""
        if t - self.touchdown_s >= t_ds_s + self.extra_ds_s:
            self.next_touchdown_s = t + t_remaining_s

    def phase(self, t: float, t_ds_s: float) -> tuple[bool, float, float]:
        """(in double stance, the phase's start, its end): the touchdown, then T_ds (the
        start's: ``start_ds_s``) to the liftoff; from the liftoff to the planned touchdown in
        single stance."""
        ds = t_ds_s + self.extra_ds_s
        in_ds = t - self.touchdown_s < ds
        start = self.touchdown_s + (0.0 if in_ds else ds)
        end = self.touchdown_s + ds if in_ds else self.next_touchdown_s
        return in_ds, start, end


def within_height(footholds: list[Foothold], z: float, max_dz: float,
                  z_other: float | None = None) -> list[Foothold]:
    """The footholds that reach into the band a foot may step to (all when max_dz <= 0).

    A foothold's corners span [z_lo, z_hi] on its plane; it is kept when that interval meets
    the band [z_top - max_dz, z_bottom + max_dz] of the feet's heights ``z`` (the stance
    foot) and ``z_other`` (where the swing foot lifted off; None: the stance foot's): no foot
    steps more than ``max_dz`` above the lower foot or below the higher one. So on stairs the
    feet climb a tread at a time (a swing from tread 1 past tread 2 to tread 3, a 30 cm rise
    in 0.3 s, caught the nosing: measured), and never into a pit. With the feet more than
    2 max_dz apart in height the band is the stance foot's own. The objects are kept, not
    copied: the solver caches its padded arrays by foothold identity, and the result only
    changes when the set does."""
    if max_dz <= 0.0:
        return footholds
    other = z if z_other is None else z_other
    lo, hi = max(z, other) - max_dz, min(z, other) + max_dz
    if lo > hi:
        lo, hi = z - max_dz, z + max_dz
    out = []
    for f in footholds:
        v = f.vertices_xy
        if len(v) == 0:
            continue
        beta, alpha = f.plane_xy
        zs = alpha + v @ beta
        if float(zs.min()) <= hi and float(zs.max()) >= lo:
            out.append(f)
    return out


class ReachableFootholds:
    """``within_height`` of the feet, recomputed only when the foothold set changes or a
    foot's height moves by 1 cm (the solver caches its arrays by the list's identity)."""

    def __init__(self, max_dz: float) -> None:
        self.max_dz = max_dz
        self._kept: tuple[list[Foothold] | None, float, float, list[Foothold]] = (
            None, math.nan, math.nan, [])

    def of(self, footholds: list[Foothold], z: float, z_other: float | None = None
           ) -> list[Foothold]:
        """The footholds reachable from the stance foot at ``z`` by the foot that lifted off
        at ``z_other``."""
        zo = z if z_other is None else z_other
        src, z_then, zo_then, kept = self._kept
        if src is not footholds or not abs(z - z_then) < 0.01 or not abs(zo - zo_then) < 0.01:
            kept = within_height(footholds, z, self.max_dz, zo)
            self._kept = (footholds, z, zo, kept)
        return kept


#: where ``foothold_ahead`` looks for a place to step: metres ahead of the stance foot along
#: the commanded direction, and to the swing foot's side of that line (a step's reach at the paper's
#: speeds: Table I's stones at d_min 35 cm leave up to ~0.55 m between footholds), every cm
#: (a 27 cm tread less the foot leaves a 3 cm window; a 17 cm beam less the foot 9 cm, which
#: probes 10 cm apart across missed with the foot 5 cm off its centre line: a stop on the
#: platform's edge, measured); ahead to twice a step from the far edge of the foothold
#: underfoot; across as far as the MPFC steps sideways on Table I's stones, from one row to
#: the next (eroded by S3, 40-50 cm: out to 35 cm, the next stone in the swing foot's row
#: was missed and a stop began on a 30 cm stone, measured at d_min 40 cm)
STEP_REACH_M = 0.60
SIDE_REACH_M = 0.50
AHEAD_PROBES_M = tuple(np.round(np.arange(0.05, 2 * STEP_REACH_M + 0.005, 0.01), 3))
SIDE_PROBES_M = tuple(np.round(np.arange(-SIDE_REACH_M, SIDE_REACH_M + 0.005, 0.01), 3))
BOTH_SIDES_M = 0.20  # (without a swing side: this far to either side)
#: how far inside the elevation map's edge a foothold can be found: S3's margin erosion
#: (margin_kernel_px 4 at 2.5 cm) against the unknown outside, and a stone's minimum area
#: (0.05 m^2: 22 cm square) left inside it
MAP_EDGE_BLIND_M = 0.25


def foothold_ahead(footholds: Sequence[Foothold], stance_xy: Sequence[float],
                   direction_xy: Sequence[float], swing_side: float = 0.0,
                   margin_m: float = 0.0,
                   seen: tuple[np.ndarray, np.ndarray] | None = None,
                   beyond: bool = False) -> bool:
    """Whether the way goes on: the foothold the stance foot is on goes on for a whole step
    (``STEP_REACH_M``) along ``direction_xy``, or another foothold lies within a step of where
    it ends (of the stance foot, standing on none). Probed at ``AHEAD_PROBES_M`` along the
    direction and ``SIDE_PROBES_M`` across it. False at the end of a course (the last stone, a
    beam's or a landing's far edge, the reachable footholds filtered by height first), where
    stepping on would step in place until the feet cross (ours; the paper's experiments end
    before).

    The ground underfoot counts only where it goes on for a whole step: counted to its edge,
    the stop began with the stance foot at the edge of the stairs' start platform (treads too
    shallow for the foot), the CoM still moving at 0.375 m/s and no room for a braking step;
    Cassie stepped in place, toppled onto the stairs and fell (measured at 19-23 cm treads).

    ``swing_side`` (+1: the swing foot is the left, -1: the right, 0: either, this far to
    either side: ``BOTH_SIDES_M``) asks for the next two steps (ours): the swing foot lands
    ``margin_m`` (the MPFC's crossover margin) or more to its side of the stance foot, and the
    step after lands as far back across from that. One step looked at: on a beam too narrow
    for two feet (13-15 cm, 5-7 cm of face) the right foot found the beam ahead, the left then
    found nothing and the stop began at the platform's edge with the CoM moving, where no
    braking step was left; Cassie rocked there for 3 s and stepped off (measured).
    Probed at every cm across, out to ``SIDE_REACH_M`` (a 9 cm beam face was
    missed between probes 10 cm apart).

    ``seen``: the box (lo, hi, world xy) where the footholds could show what is there (the
    elevation map's extent less ``MAP_EDGE_BLIND_M``; None: everywhere, ground truth). Where
    the place the way must go on (a step past the end of the foothold underfoot) lies outside
    it, nothing found is not nothing there: True, walk on (the MPFC steps only on footholds it
    has). With perception the map ends 1.25 m ahead of the CoM, where the second row of
    stones was cut off: a stop began on the first stone at 0.8 m/s, the next row showed 0.1 s
    later, and the stop on two small stones fell (measured, d_min 45 cm).

    ``beyond`` (to leave a stop): where the way goes on by another foothold, it must go on
    from there too (the nearest place the swing foot could land on it, the other foot
    swinging next). Stopped on a 30 cm tread (14 cm after S3's erosion) the gait walked on to
    the next tread, found nothing past it, stopped with the feet on two treads and fell
    (measured with perception)."""
    d = np.asarray(direction_xy, dtype=float)
    n = float(np.hypot(d[0], d[1]))
    if n < 1e-9 or not footholds:
        return bool(footholds)
    # the footholds padded into arrays once, for this look and the one past the next foothold
    # (every foothold kept: a unit normal's z is >= -1)
    world = WorldFootholds(list(footholds), -1.0)
    return _way_on(world, stance_xy, d / n, swing_side, margin_m, seen, beyond)


def _way_on(world: WorldFootholds, stance_xy: Sequence[float], d: np.ndarray,
            swing_side: float, margin_m: float, seen: tuple[np.ndarray, np.ndarray] | None,
            beyond: bool) -> bool:
    """``foothold_ahead`` on the padded footholds, along the unit direction ``d``."""
    side = np.array([-d[1], d[0]])
    ahead = np.asarray(AHEAD_PROBES_M)
    across = np.asarray(SIDE_PROBES_M)
    stance = np.asarray(stance_xy, dtype=float)[:2]
    pts = (stance + ahead[:, None, None] * d + across[None, :, None] * side).reshape(-1, 2)
    dist = np.repeat(ahead, len(across))  # each point's distance ahead
    lane = np.tile(np.arange(len(across)), len(ahead))  # ... and its lateral probe
    hits = np.zeros((len(world.index), len(pts)), dtype=np.bool_)
    underfoot = np.zeros(len(world.index), dtype=np.bool_)
    # (the vertex padding repeats a corner, so the padded rows' extremes are the boxes)
    _probe_hits(pts, stance, world.F, world.c, world.V.min(axis=1), world.V.max(axis=1),
                hits, underfoot)
    own_end, own_hits, others = 0.0, [], []
    for k in range(len(world.index)):
        hit = np.flatnonzero(hits[k])
        if underfoot[k]:  # the stance foot's own
            within = hit[dist[hit] <= STEP_REACH_M + 1e-9]
            if within.size:
                own_end = max(own_end, float(dist[within].max()))
            own_hits.append(hit)
        elif hit.size:
            others.append(hit)
    # the probes where the way goes on: the ground underfoot if it goes on for a whole step,
    # another foothold within a step of where it ends
    go = [h[dist[h] <= own_end + STEP_REACH_M + 1e-9] for h in others]
    if own_end >= STEP_REACH_M - 1e-9:
        go += own_hits
    ok = False
    if go:
        lanes = across[np.unique(lane[np.concatenate(go)])]  # lateral offsets with a way on
        if not swing_side:
            return bool(np.any(np.abs(lanes) <= BOTH_SIDES_M + 1e-9))
        u = math.copysign(1.0, swing_side) * lanes  # towards the swing foot's side
        first = u[u >= margin_m - 1e-9]
        ok = bool(first.size and np.any(u <= first.max() - margin_m + 1e-9))
    if not ok and seen is not None:
        far = stance + min(own_end + STEP_REACH_M, float(ahead[-1])) * d
        if np.any(far < seen[0]) or np.any(far > seen[1]):
            return True  # not seen yet: nothing known to stop for
    if not (ok and beyond) or own_end >= STEP_REACH_M - 1e-9:
        return ok
    probes = np.concatenate(go)
    side_ok = math.copysign(1.0, swing_side) * across[lane[probes]] >= margin_m - 1e-9
    landing = pts[probes[side_ok][np.argmin(dist[probes[side_ok]])]]
    return _way_on(world, landing, d, -swing_side, margin_m, seen, False)


@numba.njit(cache=True, nogil=True)
def _probe_hits(pts: np.ndarray, stance: np.ndarray, walls: np.ndarray, offsets: np.ndarray,
                lo: np.ndarray, hi: np.ndarray, hits: np.ndarray,
                underfoot: np.ndarray) -> None:
    """``hits[f, p]``: probe p lies in foothold f (its bounding box ``lo``-``hi`` first, then
    its walls ``walls[f] . p <= offsets[f]``, padded rows +inf, 1e-9 of slack);
    ``underfoot[f]``: so does the stance foot. One pass over footholds x probes, compiled (a
    numpy pass per foothold cost 2-4 ms a touchdown, measured)."""
    for f in range(walls.shape[0]):
        inside = True
        for k in range(walls.shape[1]):
            if walls[f, k, 0] * stance[0] + walls[f, k, 1] * stance[1] > offsets[f, k] + 1e-9:
                inside = False
                break
        underfoot[f] = inside
        lox, loy = lo[f, 0] - 1e-9, lo[f, 1] - 1e-9
        hix, hiy = hi[f, 0] + 1e-9, hi[f, 1] + 1e-9
        for p in range(pts.shape[0]):
            x, y = pts[p, 0], pts[p, 1]
            if x < lox or x > hix or y < loy or y > hiy:
                continue
            ok = True
            for k in range(walls.shape[1]):
                if walls[f, k, 0] * x + walls[f, k, 1] * y > offsets[f, k] + 1e-9:
                    ok = False
                    break
            hits[f, p] = ok


class Halt:
    """Stop where nothing ahead is reachable, and go on when something is (ours).

    At each touchdown, ``foothold_ahead`` of the new stance foot along the command. With
    nothing ahead the gait steps to a stop (desired velocity 0) and asks to stand in every
    double stance (``STOPPING``: the MPFC publishes the standing gait state there, and the OSC
    hands over to its standing controller in the first double stance with the CoM at rest, as
    for the radio's stand). It goes on (``RUNNING``) once both feet in turn find a foothold
    ahead (``WALK_ON_TOUCHDOWNS`` touchdowns in a row: a command in another direction,
    perception's new footholds), and the way goes on past the next foothold too
    (``foothold_ahead``'s ``beyond``); from rest, the node begins that stance with the
    start's weight shift (``GaitClock.from_standing``). (Going on at the first, the right
    foot on a beam too narrow for the left to pass beside it stopped, the left foot on the
    platform went on, and so on until Cassie fell: measured on a 15 cm beam.)"""

    RUNNING, STOPPING = "running", "stopping"
    WALK_ON_TOUCHDOWNS = 2

    def __init__(self) -> None:
        self.state = self.RUNNING
        self._clear = 0  # touchdowns in a row with a foothold ahead, while stopping

    def update(self, footholds: Sequence[Foothold], stance_xy: Sequence[float],
               direction_xy: Sequence[float], swing_side: float = 0.0,
               margin_m: float = 0.0,
               seen: tuple[np.ndarray, np.ndarray] | None = None) -> bool:
        """At a touchdown: the new state; True when it changed (``foothold_ahead``'s
        arguments)."""
        before = self.state
        ahead = foothold_ahead(footholds, stance_xy, direction_xy, swing_side, margin_m, seen,
                               beyond=self.state == self.STOPPING)
        self._clear = self._clear + 1 if ahead else 0
        if not ahead:
            self.state = self.STOPPING
        elif self.state == self.STOPPING and self._clear >= self.WALK_ON_TOUCHDOWNS:
            self.state = self.RUNNING
        return self.state != before


class MapHeight:
    """Height lookup on the newest elevation map (Section IX-A-3), nearest valid cell."""

    def __init__(self) -> None:
        self.grid: np.ndarray | None = None
        self.origin = np.zeros(2)
        self.res = 1.0

    def set(self, layers: Mapping[str, np.ndarray], origin_xy: Sequence[float],
            resolution: float) -> None:
        """Take the map's inpainted elevation layer, else its raw one (none: keep the last)."""
        layer = next((n for n in ("elevation_inpainted", "elevation") if n in layers), None)
        if layer is None:
            return
        self.grid = layers[layer]
        self.origin = np.asarray(origin_xy, dtype=float)
        self.res = float(resolution)

    def seen_box(self, border_m: float) -> tuple[np.ndarray, np.ndarray] | None:
        """The map's extent less ``border_m`` on every side (lo, hi world xy); None without
        a map."""
        if self.grid is None:
            return None
        rows, cols = self.grid.shape
        lo = self.origin - 0.5 * self.res + border_m
        hi = self.origin + (np.array([cols, rows]) - 0.5) * self.res - border_m
        return lo, hi

    def lookup(self, xy: np.ndarray) -> float | None:
        """Median of the 3 x 3 cells around ``xy`` (NaN cells ignored), or None off the map."""
        if self.grid is None:
            return None
        j = round((xy[0] - self.origin[0]) / self.res)
        i = round((xy[1] - self.origin[1]) / self.res)
        rows, cols = self.grid.shape
        if not (1 <= i < rows - 1 and 1 <= j < cols - 1):
            return None
        patch = self.grid[i - 1 : i + 2, j - 1 : j + 2]
        good = patch[np.isfinite(patch)]
        return float(np.median(good)) if good.size else None
