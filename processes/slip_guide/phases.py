"""Phase/side assignment (Bartlett & Manchester, Section III-E): the chosen forces grouped into
steps, each a foothold held over consecutive time steps, and a side per step.

"Consecutive forces from the same position are merged into single steps": a chosen contact
extends a step that had a contact at the previous time step within ``merge_radius_m`` of it
(neighbouring grid points count as one foothold: the l1 solution may slide a force by one
grid cell); else it starts a step. The side is "based on the contact position relative to
the CoM position": left when the step lies left of the CoM's path (in the heading's frame)
by more than ``side_deadband_m``. On a straight path the point mass has no reason to put a
foot off the centre line (the paper's robot's steps alternate there, and it says the sides
alternate "automatically"), so a step within the deadband takes the side opposite the step
before it (ours: the paper is silent on a tie).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from processes.slip_guide.planner import SlipPlan


@dataclass(frozen=True)
class Step:
    """One stance phase of one foot: where (the alpha-weighted mean of its contacts), when
    (time steps ``first``..``last`` inclusive, at ``dt_s`` each) and which foot."""

    side: str  # "left" or "right"
    position: tuple[float, float, float]
    first: int
    last: int
    dt_s: float
    lateral_m: float  # left of the CoM (in the heading frame) over its stance, mean

    @property
    def t_start_s(self) -> float:
        return self.first * self.dt_s

    @property
    def t_end_s(self) -> float:
        return (self.last + 1) * self.dt_s

    @property
    def duration_s(self) -> float:
        return self.t_end_s - self.t_start_s


def assign_phases(plan: SlipPlan, dt_s: float, merge_radius_m: float,
                  side_deadband_m: float = 0.02) -> list[Step]:
    """The plan's chosen contacts as steps in order of their start, each with a side."""
    chosen = np.flatnonzero(plan.chosen)
    groups: list[list[int]] = []  # candidate indices of each step, in time order
    for i in np.unique(plan.step[chosen]):  # at most two contacts per time step, N steps
        now = chosen[plan.step[chosen] == i]
        open_ = [g for g, m in enumerate(groups) if plan.step[m[-1]] == i - 1]
        # the closest (contact, open step) pairs first, each side used once
        d = np.array([[np.linalg.norm(plan.positions[j] - plan.positions[groups[g][-1]])
                       for g in open_] for j in now]).reshape(len(now), len(open_))
        taken: set[int] = set()
        joined: set[int] = set()
        for flat in np.argsort(d, axis=None):
            a, b = np.unravel_index(flat, d.shape)
            if d[a, b] > merge_radius_m or a in joined or b in taken:
                continue
            groups[open_[b]].append(int(now[a]))
            joined.add(int(a))
            taken.add(int(b))
        groups += [[int(now[a])] for a in range(len(now)) if a not in joined]
    groups.sort(key=lambda m: (int(plan.step[m[0]]), float(plan.positions[m[0], 0])))
    steps: list[Step] = []
    prev_side = "right"  # the first step within the deadband is the left foot
    for members in groups:
        m = np.asarray(members)
        w = plan.alpha[m]
        pos = (w[:, None] * plan.positions[m]).sum(axis=0) / w.sum()
        lateral = float(np.mean(_lateral(plan, m)))
        if abs(lateral) > side_deadband_m:
            side = "left" if lateral > 0.0 else "right"
        else:
            side = "left" if prev_side == "right" else "right"
        prev_side = side
        steps.append(Step(side, (float(pos[0]), float(pos[1]), float(pos[2])),
                          int(plan.step[m].min()), int(plan.step[m].max()), dt_s, lateral))
    return steps


def _lateral(plan: SlipPlan, idx: np.ndarray) -> np.ndarray:
    """How far left of the CoM each contact ``idx`` lies, across the CoM's heading."""
    i = plan.step[idx]
    vel = plan.s[i + 1, :2] - plan.s[i, :2]
    heading = vel / np.maximum(np.linalg.norm(vel, axis=1, keepdims=True), 1e-9)
    left = np.column_stack([-heading[:, 1], heading[:, 0]])
    return np.einsum("ij,ij->i", plan.positions[idx, :2] - plan.s[i, :2], left)
