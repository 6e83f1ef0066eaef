"""The MPFC's gait clock and what it keeps of the terrain between solves, with no LCM in it.

The clock times the gait from touchdowns (the paper's Fig. 4): a stance phase starts at each
touchdown with T_ss + T_ds remaining; the solution's stance time is taken only after T_ds
(double stance), and the swing foot's planned touchdown ends the phase. ``within_height``
and ``ReachableFootholds`` leave out footholds no leg reaches (ours, see processes/mpfc/
process.py's docstring); ``MapHeight`` is the elevation map's height lookup of Section IX-A-3.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np

from runtime.geometry import Foothold

LEFT, RIGHT = 0, 1


class GaitClock:
    """Which foot stands, since when, and when the next touchdown is (Fig. 4)."""

    def __init__(self, step_period_s: float) -> None:
        self.step_period_s = step_period_s  # T_ss + T_ds
        self.stance: int | None = None
        self.touchdown_s = 0.0
        self.next_touchdown_s = 0.0
        self._air_foot: int | None = None  # started mid-step: the foot that was in the air

    def advance(self, t: float, in_contact: Sequence[bool]) -> bool:
        """Move the clock to ``t``; a new stance at the planned touchdown. False while it
        waits to start (a foot in the air: see ``first_stance``). True when it (re)started."""
        if self.stance is None:
            stance = self.first_stance(in_contact)
            if stance is None:
                return False
            # at the first start: as if the left foot just touched down (the gait begins in
            # double stance, where the OSC hands over); restarted mid-walk: the foot that did
            self.stance = stance
            self.touchdown_s = t
            self.next_touchdown_s = t + self.step_period_s
            return True
        if t >= self.next_touchdown_s:  # touchdown of the swing foot: the stances swap
            self.stance = 1 - self.stance
            self.touchdown_s = self.next_touchdown_s
            self.next_touchdown_s = self.touchdown_s + self.step_period_s
        return False

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
        return t - self.touchdown_s

    def remaining(self, t: float) -> float:
        """T*: the nominal time left in this stance (never negative)."""
        return max(self.step_period_s - self.since_touchdown(t), 0.0)

    def plan_touchdown(self, t: float, t_remaining_s: float, t_ds_s: float) -> None:
        """A solution's stance time, taken only after double stance (Fig. 4)."""
        if self.since_touchdown(t) >= t_ds_s:
            self.next_touchdown_s = t + t_remaining_s

    def phase(self, t: float, t_ds_s: float) -> tuple[bool, float, float]:
        """(in double stance, the phase's start, its end): the touchdown, then T_ds to the
        liftoff; from the liftoff to the planned touchdown in single stance."""
        in_ds = t - self.touchdown_s < t_ds_s
        start = self.touchdown_s + (0.0 if in_ds else t_ds_s)
        end = self.touchdown_s + t_ds_s if in_ds else self.next_touchdown_s
        return in_ds, start, end


def within_height(footholds: list[Foothold], z: float, max_dz: float) -> list[Foothold]:
    """The footholds with some corner within ``max_dz`` of height ``z`` (all when max_dz <= 0).

    A foothold's corners span [z_lo, z_hi] on its plane; it is kept when that interval comes
    within ``max_dz`` of z. The objects are kept, not copied: the solver caches its padded
    arrays by foothold identity, and the result only changes when the set does."""
    if max_dz <= 0.0:
        return footholds
    out = []
    for f in footholds:
        v = f.vertices_xy
        if len(v) == 0:
            continue
        beta, alpha = f.plane_xy
        zs = alpha + v @ beta
        if float(zs.min()) - max_dz <= z <= float(zs.max()) + max_dz:
            out.append(f)
    return out



class ReachableFootholds:
    """``within_height`` of the stance foot, recomputed only when the foothold set changes or
    the stance foot moves by 1 cm in z (the solver caches its arrays by the list's identity)."""

    def __init__(self, max_dz: float) -> None:
        self.max_dz = max_dz
        self._kept: tuple[list[Foothold] | None, float, list[Foothold]] = (None, math.nan, [])

    def of(self, footholds: list[Foothold], z: float) -> list[Foothold]:
        src, z_then, kept = self._kept
        if src is not footholds or not abs(z - z_then) < 0.01:
            kept = within_height(footholds, z, self.max_dz)
            self._kept = (footholds, z, kept)
        return kept


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
