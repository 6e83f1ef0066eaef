"""What the MPFC takes from the SLIP guide's plan (ours; no LCM): its footholds narrowed to
the guide's next contact regions, and its nominal velocity.

Bartlett & Manchester's planner looks seconds ahead over a point mass; the MPFC looks two
footsteps ahead over the ALIP. As a guide, the plan's next ``count`` contact regions (the
MPFC's N + 1: the one its stance is on and its next N, in the order the plan's steps not
over yet begin) name the footholds the MPFC may choose among: those that contain or lie
within ``margin_m`` of one of them (or, for a step on no region, of its contact point).
Counted in regions, not in time: the point mass stands 0.5-1 s on a foothold where the MPFC
steps every 0.4 s, and a window of the MPFC's 0.8 s held it at a chasm's edge for 5 s, the
far side's region always beyond the window (measured). Nothing is ever narrowed to nothing:
when no foothold is left, all are kept, as they are without a fresh plan.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from runtime.codecs import GuidePlan
from runtime.geometry import Foothold


def fresh(plan: GuidePlan | None, t_s: float, max_age_s: float) -> bool:
    """Whether ``plan`` is one to follow at sim time ``t_s``: it has steps and was made from
    a state at most ``max_age_s`` before (and not after: a sim restart)."""
    return plan is not None and plan.ok and 0.0 <= t_s - plan.utime * 1e-6 <= max_age_s


def separation_xy(a: Foothold, b: Foothold) -> float:
    """The horizontal gap between two convex footholds along the best separating edge
    normal (<= 0 where they overlap): the Euclidean gap where an edge faces the other
    polygon, less than it (by up to a factor sqrt 2) between two facing corners."""
    va, vb = a.vertices_xy, b.vertices_xy
    if len(va) == 0 or len(vb) == 0:
        return np.inf
    fa, ca = a.halfspaces_xy
    fb, cb = b.halfspaces_xy
    # each edge normal of one polygon: how far beyond that edge the other's nearest corner is
    gap_b = (vb @ fa.T - ca).min(axis=0).max()
    gap_a = (va @ fb.T - cb).min(axis=0).max()
    return float(max(gap_a, gap_b))


def point_gap_xy(f: Foothold, xy: Sequence[float]) -> float:
    """How far outside the foothold's horizontal polygon the point is along its farthest
    edge normal (<= 0 inside; the Euclidean distance where an edge is nearest)."""
    fa, ca = f.halfspaces_xy
    if len(ca) == 0:
        return np.inf
    return float((fa @ np.asarray(xy, dtype=float)[:2] - ca).max())


def guide_targets(plan: GuidePlan, t_s: float, count: int
                  ) -> tuple[tuple[int, ...], list[Foothold | np.ndarray]]:
    """The plan's steps not over at ``t_s`` on its next ``count`` regions, in the order they
    begin (indices), and those regions (a step on none: its contact point)."""
    later = np.flatnonzero(plan.end_s > t_s)
    order = later[np.argsort(plan.start_s[later], kind="stable")]
    idx: list[int] = []
    seen: list[int] = []  # regions, or -1 - k for step k's point
    for k in order:
        key = int(plan.region[k]) if plan.region[k] >= 0 else -1 - int(k)
        if key not in seen:
            if len(seen) == count:
                break
            seen.append(key)
        idx.append(int(k))
    targets: list[Foothold | np.ndarray] = [
        plan.regions[r] if r >= 0 else plan.positions[-1 - r] for r in seen]
    return tuple(idx), targets


def reaching_velocity(v: np.ndarray, stance_xy: Sequence[float],
                      targets: Sequence[Foothold | np.ndarray], step_s: float,
                      max_speed_mps: float, long_step_m: float,
                      inset_m: float = 0.05) -> np.ndarray:
    """The guide's nominal velocity ``v`` (world xy); where the first of the guide's next
    regions the stance foot is not on lies more than ``long_step_m`` from the region it is on
    (from the foot, on none), lengthened along
    itself so that one nominal step of ``step_s`` (dp* = T v of the MPFC's (18)) reaches
    ``inset_m`` into it, at most ``max_speed_mps`` (ours). The point mass's mean velocity
    asks for 0.1-0.18 m steps at a chasm's edge, where one 0.6 m step crosses: the MPFC
    stepped in place there for 8 s (measured). Shorter gaps the MPFC crosses on its own (it
    stretches its steps onto the next foothold); lengthened at every gap, the walk over
    stepping stones sped up to 0.57 m/s and fell (measured)."""
    speed = float(np.hypot(v[0], v[1]))
    if speed < 1e-6 or step_s <= 0.0:
        return np.asarray(v, dtype=float)
    on: Foothold | None = None  # the region the stance foot is on
    for g in targets:
        gap = point_gap_xy(g, stance_xy) if isinstance(g, Foothold) else float(
            np.hypot(*(np.asarray(g, float)[:2] - np.asarray(stance_xy, float)[:2])))
        if gap <= 0.0 and isinstance(g, Foothold):
            if on is None:
                on = g
        elif gap > 0.0:
            # (from a stone's back edge to the next is a gap plus the stone: measured from
            # the foot, the walk over stepping stones sped up to 1.1 m/s and fell)
            apart = separation_xy(on, g) if on is not None and isinstance(g, Foothold) else gap
            if apart <= long_step_m:
                break
            need = min((gap + inset_m) / step_s, max_speed_mps)
            return np.asarray(v, dtype=float) * (max(speed, need) / speed)
    return np.asarray(v, dtype=float)


def _near(footholds: list[Foothold], targets: Sequence[Foothold | np.ndarray],
          margin_m: float) -> list[Foothold]:
    """The footholds within ``margin_m`` of a target region (or point); may be none."""
    return [f for f in footholds if any(
        (separation_xy(f, g) if isinstance(g, Foothold) else point_gap_xy(f, g)) <= margin_m
        for g in targets)]


def guided_footholds(footholds: list[Foothold], plan: GuidePlan | None, t_s: float,
                     count: int, margin_m: float, max_age_s: float) -> list[Foothold]:
    """The footholds within ``margin_m`` of the guide's next ``count`` contact regions;
    ``footholds`` itself without a fresh plan (``fresh``), or when that leaves none. The
    objects are kept, not copied (the solver caches by identity)."""
    if not footholds or plan is None or not fresh(plan, t_s, max_age_s):
        return footholds
    return _near(footholds, guide_targets(plan, t_s, count)[1], margin_m) or footholds


class GuidedFootholds:
    """``guided_footholds``, recomputed only when the footholds, the plan or its next steps
    change: the same list object otherwise, so the solver's per-list caches hold."""

    def __init__(self, count: int, margin_m: float, max_age_s: float,
                 max_speed_mps: float = 1.0, long_step_m: float = 0.55) -> None:
        self.count = count
        self.margin_m = margin_m
        self.max_age_s = max_age_s
        self.max_speed_mps = max_speed_mps  # ``reaching_velocity``'s bound ...
        self.long_step_m = long_step_m  # ... and the gap it begins at
        self._src: list[Foothold] | None = None
        self._plan: GuidePlan | None = None
        self._steps: tuple[int, ...] = ()
        self._kept: list[Foothold] = []
        #: the fresh plan's next regions at the last call ([] without one), for
        #: ``reaching_velocity``
        self.targets: list[Foothold | np.ndarray] = []
        self.narrowed = False  # the last call kept fewer than all
        self.fell_back = False  # ... a fresh plan's narrowing left none, so all were kept

    def of(self, footholds: list[Foothold], plan: GuidePlan | None, t_s: float
           ) -> list[Foothold]:
        """The footholds the MPFC may choose among at ``t_s``."""
        live = plan if plan is not None and fresh(plan, t_s, self.max_age_s) else None
        steps, targets = guide_targets(live, t_s, self.count) if live else ((), [])
        self.targets = targets
        if footholds is not self._src or live is not self._plan or steps != self._steps:
            near = _near(footholds, targets, self.margin_m) if targets else []
            self._kept = near or footholds
            self._src, self._plan, self._steps = footholds, live, steps
            self.narrowed = bool(near) and len(near) < len(footholds)
            self.fell_back = bool(targets) and bool(footholds) and not near
        return self._kept
