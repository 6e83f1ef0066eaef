"""The SLIP guide process: Bartlett & Manchester's long-horizon footstep plan as a guide for
the MPFC, a few times a second.

Periodic (``rate_hz`` in hw_config/processes.yaml): each tick plans from the newest robot
state (the CoM's position and velocity, ``processes.kinematics``) along the command (a
straight path at the commanded speed and heading, ``reference_path``, on a line held in
the world, ``ReferenceLine``) over the newest
foothold set (S3's, or the sim's ground truth), and publishes the plan's steps, each with
the foothold it is on, and the CoM's mean velocity over the MPFC's next steps
(``guide_plan_t``; the MPFC's side: ``processes.mpfc.guide``). Without a state, footholds
or a solution it publishes a plan-less message that says why, and the MPFC goes on
unguided. Time is the state's ``utime``.

Warm start: none beyond the candidates. The planner is a pure function of its inputs and
piqp takes no warm start (``processes.slip_guide.planner``); the footholds' candidate points
are sampled once per foothold set over a box around the robot and reused while the path
stays inside it.
"""

from __future__ import annotations

import math
import time
from collections import deque
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from lcmtypes import command_t, foothold_set_t, guide_plan_t, robot_state_t
from processes.kinematics import AlipKinematics
from processes.slip_guide.candidates import Candidates, sample_footholds, surface_height
from processes.slip_guide.params import SlipParams
from processes.slip_guide.phases import Step, assign_phases
from processes.slip_guide.planner import SOLVED, SlipPlan, SlipPlanner, reference_path
from runtime.codecs import (
    GUIDE_OK,
    SIDE_LEFT,
    SIDE_RIGHT,
    FootholdSetReader,
    GuidePlan,
    guide_plan_to_msg,
    no_guide_plan,
)
from runtime.config_types import ProcessConfig, Profile
from runtime.geometry import Foothold
from runtime.node import Node
from runtime.params import spec

#: the gains file's variants: ``table1`` its top level (the benchmark's), ``guide`` this
#: process's longer horizon
VARIANTS = ("guide", "table1")
#: candidates are sampled this far beyond what one plan needs, so the next plans reuse them
CANDIDATE_SLACK_M = 1.0

#: plan times kept for the counters (an hour at 4 Hz)
PLAN_TIMES_KEPT = 14400

#: the gains file (hw_config/gains/slip_guide.yaml), in the variant ``Params.variant`` names
Gains = SlipParams


@dataclass(frozen=True)
class Params:
    """The guide's ``params:`` (hw_config/processes.yaml, and the profiles' overrides)."""

    variant: str = spec("guide", choices=VARIANTS)  # of the gains file
    #: desired velocity [vx, vy] until the first command, pelvis-yaw frame (the MPFC's)
    default_velocity: tuple[float, float] = spec((0.375, 0.0), unit="m/s")
    #: the nominal velocity is the planned CoM's mean over this much of the plan: the MPFC's
    #: horizon, N = 2 steps of T_ss + T_ds (hw_config/gains/mpfc.yaml)
    velocity_window_s: float = spec(0.8, lo=0.0, lo_open=True, hi=20.0, unit="s")
    #: the reference path is a line fixed in the world (``ReferenceLine``), laid anew only
    #: when the commanded heading leaves it by more than this (a turn, not the operator's
    #: few degrees of heading correction)
    relay_turn_deg: float = spec(20.0, lo=0.0, hi=180.0, unit="deg")
    #: ... and each plan's path starts at the CoM and comes back onto the line over this
    line_return_s: float = spec(1.0, lo=0.0, hi=10.0, unit="s")
    #: candidates farther across from the line than this are left out (0: none are)
    corridor_m: float = spec(0.35, lo=0.0, hi=10.0, unit="m")


class CandidateCache:
    """The foothold set's candidate points over a box, resampled only when the set changes
    or a plan's box leaves the sampled one."""

    def __init__(self, spacing_m: float) -> None:
        self.spacing_m = spacing_m
        self._src: list[Foothold] | None = None
        self._box = (0.0, 0.0, 0.0, 0.0)
        self._cands: Candidates | None = None

    def of(self, footholds: list[Foothold], box: tuple[float, float, float, float]
           ) -> Candidates:
        """Candidates covering ``box`` = (x_min, x_max, y_min, y_max)."""
        b = self._box
        inside = box[0] >= b[0] and box[1] <= b[1] and box[2] >= b[2] and box[3] <= b[3]
        if self._cands is None or footholds is not self._src or not inside:
            s = CANDIDATE_SLACK_M
            self._box = (box[0] - s, box[1] + s, box[2] - s, box[3] + s)
            self._cands = sample_footholds(footholds, self.spacing_m, self._box)
            self._src = footholds
        return self._cands


class ReferenceLine:
    """Where the reference path runs (ours): a line fixed in the world along the commanded
    heading, laid through the CoM when the guide starts, when the command's speed changes or
    its heading leaves the line's by more than ``relay_turn_rad``; each plan's path runs from
    the CoM's foot on it, shifted to begin at the CoM (``back_to_line``). (From the CoM afresh
    every plan, the paths wandered with the robot across the stepping stones' three columns
    and led the MPFC off the course's side at 9.3 s, measured: the paper takes s* from "a
    higher level planner or remote operator", which holds a line.)"""

    def __init__(self, relay_turn_rad: float) -> None:
        self.relay_turn_rad = relay_turn_rad
        self.origin: np.ndarray | None = None
        self.heading = 0.0
        self.speed = math.nan
        self.relays = 0  # lines laid

    def start(self, com_xy: np.ndarray, heading: float, speed: float) -> np.ndarray:
        """The path's start for a CoM at ``com_xy`` under a command along ``heading``."""
        turned = abs(math.remainder(heading - self.heading, 2.0 * math.pi))
        if self.origin is None or speed != self.speed or turned > self.relay_turn_rad:
            self.origin, self.heading, self.speed = np.array(com_xy[:2], float), heading, speed
            self.relays += 1
        u = np.array([math.cos(self.heading), math.sin(self.heading)])
        return self.origin + float((np.asarray(com_xy[:2]) - self.origin) @ u) * u

    def within(self, cands: Candidates, corridor_m: float) -> Candidates:
        """The candidates at most ``corridor_m`` across from the line (all: 0, or no line).
        The point mass reaches 0.53 m to either side and its l1 choice took the stepping
        stones' side columns, which the MPFC, narrowed to them, reached by 0.55 m steps
        sideways and fell off the course's side (measured: 29 falls in 80 trials against 1
        without the guide); the paper's path tolerance bounds the CoM, not its contacts."""
        if corridor_m <= 0.0 or self.origin is None or len(cands) == 0:
            return cands
        n = np.array([-math.sin(self.heading), math.cos(self.heading)])
        keep = np.abs((cands.points[:, :2] - self.origin) @ n) <= corridor_m
        if keep.all():
            return cands
        return Candidates(cands.points[keep], cands.normals[keep], cands.cost[keep])

    @staticmethod
    def back_to_line(s_ref: np.ndarray, off_xy: np.ndarray, dt_s: float, return_s: float
                     ) -> tuple[np.ndarray, np.ndarray]:
        """The path along the line (``reference_path`` from ``start``), shifted by the CoM's
        offset ``off_xy`` from it at its start and back onto the line linearly over
        ``return_s``; with its velocity. The planner holds its CoM within the path tolerance
        of the path at every sample (10 cm, Fig. 4): a path on the line itself from the first
        sample made 25-55 % of the plans infeasible where the walk had swayed or drifted off
        it (measured on the stones)."""
        t = np.arange(len(s_ref)) * dt_s
        w = np.clip(1.0 - t / return_s, 0.0, 1.0) if return_s > 0.0 else (t == 0.0) * 1.0
        out = s_ref.copy()
        out[:, :2] += w[:, None] * np.asarray(off_xy, dtype=float)[:2]
        return out, np.diff(out, axis=0) / dt_s


def region_of(footholds: list[Foothold], xy: np.ndarray) -> int:
    """The index of the foothold holding ``xy``, else of the nearest by its farthest edge
    (a step's alpha-weighted mean may fall between two grid points' footholds); -1 for
    none."""
    best, gap = -1, math.inf
    for i, f in enumerate(footholds):
        fa, ca = f.halfspaces_xy
        if len(ca) == 0:
            continue
        g = float((fa @ xy[:2] - ca).max())
        if g <= 0.0:
            return i
        if g < gap:
            best, gap = i, g
    return best


def guide_plan(plan: SlipPlan, steps: list[Step], footholds: list[Foothold], utime: int,
               window_s: float, dt_s: float) -> GuidePlan:
    """A solved plan as the message's content: steps in sim time, each on its region, and the
    CoM's mean velocity over ``window_s`` (its displacement over that time)."""
    t0 = utime * 1e-6
    idx = [region_of(footholds, np.asarray(s.position)) for s in steps]
    used = sorted({i for i in idx if i >= 0})
    where = {i: k for k, i in enumerate(used)}
    m = max(1, min(round(window_s / dt_s), len(plan.s) - 1))
    v = (plan.s[m, :2] - plan.s[0, :2]) / (m * dt_s)
    return GuidePlan(
        utime, np.array([s.position for s in steps]).reshape(-1, 3),
        np.array([t0 + s.t_start_s for s in steps]), np.array([t0 + s.t_end_s for s in steps]),
        np.array([SIDE_LEFT if s.side == "left" else SIDE_RIGHT for s in steps], dtype=int),
        np.array([where.get(i, -1) for i in idx], dtype=int),
        tuple(footholds[i] for i in used), v, GUIDE_OK,
        f"{len(steps)} steps, {plan.iterations} QPs ({plan.stopped})")


class SlipGuideNode(Node):
    """State, footholds and command in; the guide's plan out, at ``rate_hz``."""

    name = "slip_guide"
    inputs = {"state": robot_state_t, "footholds": foothold_set_t, "command": command_t}
    outputs = {"plan": guide_plan_t}
    trigger_role = None  # periodic

    def __init__(self, params: SlipParams, default_velocity: tuple[float, float],
                 velocity_window_s: float, relay_turn_deg: float = 20.0,
                 line_return_s: float = 1.0, corridor_m: float = 0.35) -> None:
        self.params = params
        self.line = ReferenceLine(math.radians(relay_turn_deg))
        self.return_s = line_return_s
        self.corridor_m = corridor_m
        self.planner = SlipPlanner(params)
        self.kin = AlipKinematics()
        self.vdes = np.array(default_velocity, dtype=float)
        self.window_s = velocity_window_s
        self._holds = FootholdSetReader()  # the channel's newest set
        self.footholds: list[Foothold] = []
        self.cache = CandidateCache(params.candidate_spacing_m)
        self.last_status = "no state yet"
        self.plans = 0  # ticks with a plan
        self.failures = 0  # ticks with a state but no plan
        #: the plans' wall times, ms (candidates + Algorithm 1), the newest PLAN_TIMES_KEPT
        self.plan_ms: deque[float] = deque(maxlen=PLAN_TIMES_KEPT)
        self.qp_solves = 0

    def _read_inputs(self, inbox: Any) -> None:
        if inbox.is_fresh("command"):
            cmd = inbox.latest("command")
            if cmd is not None and all(math.isfinite(x) for x in (cmd.vx, cmd.vy)):
                self.vdes[:] = (cmd.vx, cmd.vy) if cmd.mode == 0 else (0.0, 0.0)
        if inbox.is_fresh("footholds") and self._holds.read(inbox.latest("footholds")):
            self.footholds = self._holds.footholds

    def tick(self, ctx: Any, inbox: Any) -> None:
        self._read_inputs(inbox)
        state = inbox.latest("state")
        if state is None:
            return
        out = self.plan(state)
        self.last_status = out.status_text
        if out.ok:
            self.plans += 1
            self.plan_ms.append(out.plan_wall_ms)
            self.qp_solves += out.qp_solves
        else:
            self.failures += 1
        ctx.publish("plan", guide_plan_to_msg(out))

    def plan(self, state: robot_state_t) -> GuidePlan:
        """The guide's plan from ``state`` over the footholds held (no LCM: the tick's)."""
        utime = state.header.utime
        q = np.asarray(state.q, dtype=float)
        v = np.asarray(state.v, dtype=float)
        if not self.kin.accepts(q, v):
            return no_guide_plan(utime, "bad state (NaN or wrong size)")
        if not self.footholds:
            return no_guide_plan(utime, "no footholds yet")
        p = self.params
        t0 = time.perf_counter()
        self.kin.update(q, v)
        yaw = self.kin.pelvis_yaw()
        heading = yaw + math.atan2(self.vdes[1], self.vdes[0])
        speed = float(np.hypot(*self.vdes))
        holds = self.footholds
        start = self.line.start(self.kin.com[:2], heading, speed)
        try:
            s_ref, v_ref = reference_path(start, self.line.heading, speed, p,
                                          lambda xy: surface_height(holds, xy))
        except ValueError as exc:  # no ground under the whole path
            return no_guide_plan(utime, str(exc))
        s_ref, v_ref = self.line.back_to_line(s_ref, self.kin.com[:2] - start, p.dt_s,
                                              self.return_s)
        r = p.reach_m
        box = (float(s_ref[:, 0].min() - r), float(s_ref[:, 0].max() + r),
               float(s_ref[:, 1].min() - r), float(s_ref[:, 1].max() + r))
        cands = self.line.within(self.cache.of(holds, box), self.corridor_m)
        plan = self.planner.plan(self.kin.com, self.kin.com_vel, s_ref, v_ref, cands)
        if plan.status != SOLVED:
            return no_guide_plan(utime, f"no plan: {plan.status} ({len(cands)} candidates)")
        steps = assign_phases(plan, p.dt_s, p.merge_radius_m)
        out = guide_plan(plan, steps, holds, utime, self.window_s, p.dt_s)
        return replace(out, footholds_seq=self._holds.seq, horizon_s=p.horizon_s,
                       plan_wall_ms=(time.perf_counter() - t0) * 1e3,
                       qp_solves=plan.iterations)

    def status(self) -> str:
        return f"{self.plans} plans, {self.failures} without one; last: {self.last_status}"

    def counters(self) -> dict[str, float]:
        """Plans made, ticks without one, QPs solved, and the plans' wall time (mean, max:
        the sampling of candidates and Algorithm 1, ms)."""
        ms = self.plan_ms
        return {"plans": float(self.plans), "failures": float(self.failures),
                "qp_solves": float(self.qp_solves),
                "plan_ms_mean": float(np.mean(ms)) if ms else 0.0,
                "plan_ms_max": float(max(ms)) if ms else 0.0}


def make_node(proc: ProcessConfig, profile: Profile, params: Params, gains: SlipParams) -> Node:
    """The guide from hw_config (gains: the SLIP planner's, in ``params.variant``)."""
    node = SlipGuideNode(gains, params.default_velocity, params.velocity_window_s,
                         params.relay_turn_deg, params.line_return_s, params.corridor_m)
    node.name = proc.name
    return node
