"""The MPFC process: the laptop's footstep controller, wired to the bus.

Driven by the newest robot state for the laptop (``NETWORK_CASSIE_STATE``), it keeps the gait
timing of Section IV / Fig. 4: an MPFC stance phase starts at each touchdown with a nominal
T_ss + T_ds remaining, and the footstep and timing solutions are ignored until T_ds after
touchdown (double stance). It publishes the next footstep (its height looked up on the
elevation map when one is available, Section IX-A-3), the previous and next switch times, the
gait state and the ankle torque, plus the solve internals. A failed solve keeps the previous
plan, as on the robot. Time is the robot state's ``utime``: no wall clock decides anything.

Footholds come from ``params.footholds``: ``channel`` (the foothold set from S3, or the
sim's ground truth of its terrain: ``publish_footholds``) or ``flat`` (level ground around
the robot). (A robot process knows no terrain file: the truth comes over the bus.)

Footholds wholly more than ``params.foothold_max_height_m`` (default 0.2 m) above the lower
foot or below the higher one (the stance foot, and the swing foot where it lifted off) are left
out of the solve (ours, not in the paper): the MPFC's costs do not see footstep height (R has
a zero z weight, Table V), so it would otherwise take a level-looking step into a pit or off a
landing that S3 rightly finds flat and safe, but that no leg reaches, or swing a foot past a
tread to the next (``processes.mpfc.gait.within_height``). Where none of the reachable
footholds lies ahead within a step (the end of a course), the gait steps to a stop and stands,
and says so (``processes.mpfc.gait.Halt``; ours): stepping on in place ended with the feet
crossed and a fall, measured at the end of a stepping-stone course.

With ``params.guide`` (ours, issue 20), the SLIP guide's plan (``guide_plan_t``, a few Hz:
``processes.slip_guide.process``) guides the solve while it is fresh (``guide_max_age_s``):
the reachable footholds are narrowed to those within ``guide_margin_m`` of the guide's
next N + 1 contact regions (the stance's and the MPFC's N footsteps'), all of them where that
leaves none, and the desired velocity -- the nominal step of (18) -- is the guide's CoM
velocity over the MPFC's horizon, lengthened so one nominal step reaches the guide's next
region where that is farther than ``guide_long_step_m`` (up to ``guide_max_speed_mps``;
``processes.mpfc.guide``). The stop for nothing ahead looks
at every reachable foothold, as without the guide. A radio's stand is never overridden.
"""

from __future__ import annotations

import dataclasses
import logging
import math
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from lcmtypes import (
    command_t,
    elevation_map_t,
    foothold_set_t,
    guide_plan_t,
    mpfc_debug_t,
    mpfc_output_t,
    robot_state_t,
)
from processes.dcm_planner.params import DcmParams
from processes.dcm_planner.solver import DcmSolver
from processes.kinematics import AlipKinematics
from processes.mpfc.gait import (
    MAP_EDGE_BLIND_M,
    GaitClock,
    Halt,
    MapHeight,
    ReachableFootholds,
    foothold_ahead,
    within_height,
)
from processes.mpfc.guide import GuidedFootholds, fresh, reaching_velocity
from processes.mpfc.params import MpfcParams
from processes.mpfc.solver import MpfcSolution, MpfcSolver, SupportTransfer
from runtime.codecs import (
    FootholdSetReader,
    GuidePlan,
    elevation_map_from_msg,
    guide_plan_from_msg,
)
from runtime.config_types import ProcessConfig, Profile
from runtime.errors import ConfigError
from runtime.geometry import Foothold
from runtime.node import Node
from runtime.params import load, spec

log = logging.getLogger(__name__)

LEFT, RIGHT = 0, 1
# (mpfc_output_t's consts: the one list of the gait's phases)
GAIT_SS = (mpfc_output_t.GAIT_LEFT_SS, mpfc_output_t.GAIT_RIGHT_SS)  # single stance on l / r
GAIT_DS = (mpfc_output_t.GAIT_DS_AFTER_LEFT, mpfc_output_t.GAIT_DS_AFTER_RIGHT)  # after l / r
GAIT_STANDING = mpfc_output_t.GAIT_STANDING
STATUS = {"optimal": 0, "time_limited": 1, "infeasible": 2}
DEFAULT_MAX_HEIGHT_M = 0.2  # one 15 cm tread (Fig. 11), Table I's stone heights, and a margin
#: the crossover margin while stepping to a stop (ours): the OSC stands only on feet 7 cm or
#: more apart across (``processes.osc.controller.STAND_MIN_WIDTH_M``); with the gait's 6 cm a
#: stop on one stone ended with the feet 5 cm apart and in line, stepping until it fell
STOP_CROSSOVER_M = 0.10
VARIANTS = ("hardware", "simulation")  # the columns of Table V

#: the gains file (hw_config/gains/mpfc.yaml): Table V, in the column ``Params.variant`` names
Gains = MpfcParams


@dataclass(frozen=True)
class Params:
    """The MPFC's ``params:`` (hw_config/processes.yaml, and the profiles' overrides)."""

    variant: str = spec("simulation", choices=VARIANTS)  # the column of Table V
    #: where the footholds come from: channel | flat (module docstring)
    footholds: str = spec("channel", choices=("channel", "flat"))
    #: desired velocity [vx, vy] until the first command, pelvis-yaw frame
    default_velocity: tuple[float, float] = spec((0.375, 0.0), unit="m/s")
    #: footholds wholly farther than this above or below the stance foot are left out (ours,
    #: module docstring); 0: no limit
    foothold_max_height_m: float = spec(DEFAULT_MAX_HEIGHT_M, lo=0.0, unit="m")
    #: the next footstep's height from the elevation map when there is one (Section IX-A-3)
    height_lookup: bool = True
    #: the footstep planner: mpfc (Acosta & Posa, the gains file) or dcm (Xiang et al.'s
    #: variable-timing DCM MIQP, ``processes.dcm_planner``; its gains in ``dcm_gains``)
    planner: str = spec("mpfc", choices=("mpfc", "dcm"))
    #: the DCM planner's gains file, relative to the profile's hw_config folder (or absolute)
    dcm_gains: str = "gains/dcm_planner.yaml"
    #: the DCM planner's ablation: A the planner, B fixed step, C N = 2, D no viability
    dcm_variant: str = spec("A", choices=("A", "B", "C", "D"))
    #: follow the SLIP guide's plan (input ``guide``, module docstring); off: as without one
    guide: bool = False
    #: a guide plan older than this (from the state it began at) is not followed
    guide_max_age_s: float = spec(0.6, lo=0.0, lo_open=True, hi=10.0, unit="s")
    #: footholds within this of the guide's next contact regions are kept
    guide_margin_m: float = spec(0.10, lo=0.0, hi=2.0, unit="m")
    #: the guide's velocity is lengthened so one nominal step reaches its next region, up to
    #: this (``processes.mpfc.guide.reaching_velocity``; the command's range)
    guide_max_speed_mps: float = spec(1.0, lo=0.0, hi=3.0, unit="m/s")
    #: ... where that region is farther than this from the stance foot: the gaps between
    #: Table I's footholds (shrunk for the foot) are 0.31-0.52 m, which the MPFC alone crosses
    #: at the command (d_min 35-70 cm, seeds 2000-2009); a chasm's 0.59 m it does not
    guide_long_step_m: float = spec(0.55, lo=0.0, hi=3.0, unit="m")


class FootstepSolver(Protocol):
    """What the node asks of a footstep planner (MpfcSolver, DcmSolver): a plan from the ALIP
    state about the stance foot, and forgetting the previous one at a gait restart."""

    def solve(self, x_alip: np.ndarray, stance: str, p_stance: np.ndarray,
              t_remaining_s: float, vdes: np.ndarray, footholds: list[Foothold],
              yaw: float = 0.0, transfer: SupportTransfer | None = None
              ) -> MpfcSolution: ...

    def reset(self) -> None: ...


class MpfcNode(Node):
    """The MPFC loop: gait timing, ALIP state, foothold set, solve, plan."""

    name = "mpfc"
    inputs = {
        "state": robot_state_t,
        "footholds": foothold_set_t,
        "elevation_map": elevation_map_t,
        "command": command_t,
    }
    outputs = {"plan": mpfc_output_t, "debug": mpfc_debug_t}
    trigger_role = "state"

    def __init__(
        self,
        params: MpfcParams,
        source: str,
        static_footholds: list[Foothold],
        default_velocity: tuple[float, float],
        height_lookup: bool,
        max_height_m: float = DEFAULT_MAX_HEIGHT_M,
        solver: FootstepSolver | None = None,
        guide: GuidedFootholds | None = None,
    ) -> None:
        self.params = params
        #: the SLIP guide (``Params.guide``): an input of its own, and what it narrows
        self.guide = guide
        if guide is not None:
            self.inputs = {**type(self).inputs, "guide": guide_plan_t}
        self.guide_plan: GuidePlan | None = None
        self.standing_cmd = False  # the radio asks to stand: no guide overrides it
        self.guided = 0  # solves with a fresh guide plan
        self.guide_narrowed = 0  # ... of which with fewer footholds than without
        self.guide_fallbacks = 0  # ... of which the narrowing left none and all were kept
        # (the gait clock is the MPFC's, T_ss + T_ds, whichever planner plans the steps)
        self.solver: FootstepSolver = solver if solver is not None else MpfcSolver(params)
        #: the MPFC's stop margin (``STOP_CROSSOVER_M``); None for a planner without one (DCM)
        self._set_margin = getattr(self.solver, "set_crossover_margin", None)
        self.kin = AlipKinematics()
        self.source = source
        self.footholds = static_footholds
        self._holds = FootholdSetReader()  # the channel's newest set
        self.vdes = np.array(default_velocity, dtype=float)
        self.height_lookup = height_lookup
        self.max_height_m = max_height_m
        self._reachable = ReachableFootholds(max_height_m)
        self.map = MapHeight()
        self.clock = GaitClock(params.t_s2s_s, params.t_ds_s, params.t_ds_start_s)
        self.halt = Halt()
        self.stance: int | None = None  # the clock's, as of the last tick
        self.stance_pos = np.zeros(3)
        #: where the swing foot lifted off (at the stance's start, both feet down): the
        #: previous stance foot, and the height the reachable footholds are banded by
        self.liftoff_pos = np.zeros(3)
        self.plan: MpfcSolution | None = None
        self.last_status = "none"
        self.solves = 0
        self.failures = 0
        self.halts = 0  # times it stopped because no foothold ahead was within a step
        self.halt_since_s = -1.0  # sim time the current stop began (-1: walking on)
        self.halt_xy = (math.nan, math.nan)  # ... and where the stance foot was then
        self.vdes_used = self.vdes  # the desired velocity of the last solve (the guide's)

    def warm_up(self) -> None:
        """Compile (or load from numba's cache) the look ahead's probe kernel before the loop
        starts: its first call took 0.2-0.6 s, at the first touchdown (measured)."""
        square = Foothold.from_polygon(np.array([[0.0, -0.5], [1.0, -0.5], [1.0, 0.5],
                                                 [0.0, 0.5]]))
        foothold_ahead([square], (0.5, 0.0), (1.0, 0.0), 1.0, 0.06)

    # -- inputs --------------------------------------------------------------------------------
    def _read_inputs(self, inbox: Any) -> None:
        if inbox.is_fresh("command"):
            cmd = inbox.latest("command")
            if cmd is not None and all(math.isfinite(x) for x in (cmd.vx, cmd.vy)):
                # a stand: step to a stop (desired velocity 0) and keep planning; the OSC
                # hands over to standing in double stance once the CoM has come to rest
                # (planning "standing" at once left it to brake a walking robot on its feet)
                self.vdes[:] = (cmd.vx, cmd.vy) if cmd.mode == 0 else (0.0, 0.0)
                self.standing_cmd = cmd.mode != 0
        if self.guide is not None and inbox.is_fresh("guide"):
            g = inbox.latest("guide")
            if g is not None:
                self.guide_plan = guide_plan_from_msg(g)
        if (self.source == "channel" and inbox.is_fresh("footholds")
                and self._holds.read(inbox.latest("footholds"))):
            self.footholds = self._holds.footholds
        if self.height_lookup and inbox.is_fresh("elevation_map"):
            m = inbox.latest("elevation_map")
            if m is not None:
                layers = elevation_map_from_msg(m)
                if isinstance(layers, dict):  # else malformed: the last good map stays
                    self.map.set(layers, m.origin, m.resolution)

    # -- the loop ------------------------------------------------------------------------------
    def tick(self, ctx: Any, inbox: Any) -> None:
        state = inbox.trigger()
        self._read_inputs(inbox)
        q = np.asarray(state.q, dtype=float)
        v = np.asarray(state.v, dtype=float)
        if not self.kin.accepts(q, v):
            self.last_status = "bad state (NaN or wrong size): plan kept"
            self._publish(ctx, state, None, "error")
            return
        t = state.header.utime * 1e-6
        self.kin.update(q, v)
        yaw = self.kin.pelvis_yaw()
        p = self.params
        clock = self.clock
        at_rest = bool(np.hypot(v[0], v[1]) < 0.1)
        if clock.advance(t, state.in_contact, at_rest):
            self.solver.reset()
        if clock.stance is None:
            self.last_status = ("started with a foot in the air: waiting for its touchdown "
                                "to take the gait from the robot")
            return
        stance_before, self.stance = self.stance, clock.stance
        if self.stance != stance_before:  # a touchdown (or the start): both feet down
            self.liftoff_pos = self.kin.foot_points[1 - self.stance].copy()
        self.stance_pos = self.kin.foot_points[self.stance].copy()
        t_star = clock.remaining(t)
        x = self.kin.alip_state(self.stance_pos, yaw)
        # The command is in the pelvis-yaw frame, which is the stance frame's orientation.
        c, s = math.cos(yaw), math.sin(yaw)
        ahead = (c * self.vdes[0] - s * self.vdes[1], s * self.vdes[0] + c * self.vdes[1])
        # (ahead: what the stance foot reaches, for the next two steps: on stairs the tread
        # above the upper foot is out of the swing foot's band but the step after takes it)
        if self.stance != stance_before and self.halt.update(
                within_height(self.footholds, float(self.stance_pos[2]), self.max_height_m),
                self.stance_pos[:2], ahead, 1.0 if self.stance == RIGHT else -1.0,
                p.crossover_margin_m, self.map.seen_box(MAP_EDGE_BLIND_M)):
            log.warning("MPFC at t=%.2f s, stance foot at (%.2f, %.2f): %s", t,
                        self.stance_pos[0], self.stance_pos[1], self._halt_text())
            stopping = self.halt.state == Halt.STOPPING
            self.halts += stopping
            self.halt_since_s = t if stopping else -1.0
            self.halt_xy = ((float(self.stance_pos[0]), float(self.stance_pos[1])) if stopping
                            else (math.nan, math.nan))
            if not stopping and at_rest and all(state.in_contact):
                clock.from_standing(t)  # walking on from standing: the start's weight shift
                self.solver.reset()
        in_ds, _, liftoff = clock.phase(t, p.t_ds_s)
        stopping = self.halt.state == Halt.STOPPING
        vdes, footholds = self._guided(t, yaw)
        if self._set_margin is not None:
            self._set_margin(max(STOP_CROSSOVER_M, p.crossover_margin_m) if stopping
                             else p.crossover_margin_m)
        sol = self.solver.solve(
            x,
            "left" if self.stance == LEFT else "right",
            self.stance_pos,
            t_star,
            np.zeros(2) if stopping else vdes,
            footholds,
            yaw=yaw,
            transfer=SupportTransfer(self.liftoff_pos, liftoff - t if in_ds else 0.0,
                                     p.t_ds_s + clock.extra_ds_s),
        )
        self.solves += 1
        self.last_status = sol.status if self.halt.state == Halt.RUNNING else \
            f"{sol.status}; {self._halt_text()}"
        if sol.has_plan:  # (its stance time is ignored during double stance, Fig. 4)
            clock.plan_touchdown(t, sol.t_remaining_opt_s, p.t_ds_s)
            self.plan = sol
        else:
            self.failures += 1
        self._publish(ctx, state, sol, sol.status, yaw, x)

    def _halt_text(self) -> str:
        if self.halt.state == Halt.RUNNING:
            return "a foothold ahead within a step: walking on"
        return ("no foothold ahead within a step: stepping to a stop and standing (a command "
                "another way or new footholds ahead walk on)")

    def _reachable_footholds(self) -> list[Foothold]:
        return self._reachable.of(self.footholds, float(self.stance_pos[2]),
                                 float(self.liftoff_pos[2]))

    def _guided(self, t: float, yaw: float) -> tuple[np.ndarray, list[Foothold]]:
        """The desired velocity (stance frame) and the footholds of this solve: the
        command's and the reachable ones, or with a fresh guide plan its nominal velocity
        and the reachable footholds it narrows to (module docstring)."""
        reachable = self._reachable_footholds()
        plan = self.guide_plan
        self.vdes_used = self.vdes
        if self.guide is None or plan is None or not fresh(plan, t, self.guide.max_age_s):
            return self.vdes, reachable
        self.guided += 1
        kept = self.guide.of(reachable, plan, t)
        self.guide_narrowed += self.guide.narrowed
        self.guide_fallbacks += self.guide.fell_back
        if not self.standing_cmd:
            c, s = math.cos(yaw), math.sin(yaw)
            # world -> the command's frame, the pelvis yaw's
            vx, vy = reaching_velocity(plan.nominal_velocity, self.stance_pos[:2],
                                       self.guide.targets, self.params.t_s2s_s,
                                       self.guide.max_speed_mps, self.guide.long_step_m)
            self.vdes_used = np.array([c * vx + s * vy, -s * vx + c * vy])
        return self.vdes_used, kept

    # -- outputs -------------------------------------------------------------------------------
    def _publish(
        self,
        ctx: Any,
        state: robot_state_t,
        sol: MpfcSolution | None,
        status: str,
        yaw: float = 0.0,
        x_alip: np.ndarray | None = None,
    ) -> None:
        out = mpfc_output_t()
        out.header.utime = state.header.utime
        t = state.header.utime * 1e-6
        plan = self.plan
        if self.stance is None or plan is None or plan.footsteps is None:
            out.gait_state = GAIT_STANDING
            out.stance = LEFT if self.stance is None else self.stance
            out.solve_status = 3 if status == "error" else STATUS.get(status, 3)
        else:
            in_ds, start, end = self.clock.phase(t, self.params.t_ds_s)
            out.gait_state = (GAIT_DS if in_ds else GAIT_SS)[self.stance]
            if in_ds and self.halt.state == Halt.STOPPING:
                out.gait_state = GAIT_STANDING  # stand here: the OSC hands over at rest
            out.stance = self.stance
            step = plan.footsteps[0].copy()
            if self.height_lookup:
                z = self.map.lookup(step[:2])
                if z is not None:
                    step[2] = z
            out.next_footstep_world = step.tolist()
            c, s = math.cos(yaw), math.sin(yaw)
            d = step - self.stance_pos
            out.next_footstep = [c * d[0] + s * d[1], -s * d[0] + c * d[1], d[2]]
            out.stance_foot_world = self.stance_pos.tolist()
            out.stance_yaw = yaw
            # the current gait phase: touchdown to liftoff (T_ds, Fig. 4) in double stance,
            # liftoff to the planned touchdown in single stance
            out.prev_switch_time_s, out.next_switch_time_s = start, end
            out.ankle_torque = 0.0 if in_ds else float(plan.ankle_torque_nm)
            out.num_footsteps = len(plan.footsteps)
            out.footsteps_world = plan.footsteps.tolist()
            out.solve_status = STATUS.get(status, 3)
        out.desired_velocity = self.vdes_used.tolist()
        ctx.publish("plan", out)
        dbg = mpfc_debug_t()
        dbg.header.utime = state.header.utime
        if sol is not None:
            dbg.solve_wall_ms = sol.solve_wall_ms
            dbg.optimizer_ms = sol.optimizer_ms
            dbg.nodes_explored = sol.nodes_explored
            dbg.num_footholds = sol.footholds_considered
            chosen = list(sol.foothold_indices or ())
            dbg.num_steps = len(chosen)
            dbg.chosen_footholds = chosen
            dbg.objective = float(sol.objective) if math.isfinite(sol.objective) else 0.0
            if sol.alip_states is not None:
                dbg.solution = np.asarray(sol.alip_states, dtype=float).ravel().tolist()
                dbg.solution_size = len(dbg.solution)
        dbg.status = STATUS.get(status, 3)
        dbg.status_text = (
            self.last_status if sol is None or sol.has_plan else f"{status}: previous plan kept"
        )
        if x_alip is not None:  # the ALIP state this solve started from
            dbg.initial_alip = x_alip.tolist()
        ctx.publish("debug", dbg)

    def status(self) -> str:
        return f"{self.solves} solves, {self.failures} kept the previous plan; {self.last_status}"

    def counters(self) -> dict[str, float]:
        """Solves, failed solves, and the stops for nothing reachable ahead (``halted``: 1
        while stopping or stopped, since ``halt_since_s`` of sim time, the stance foot then
        at ``halt_x``, ``halt_y``); with the guide, the solves it guided (``guided``), those
        with fewer footholds for it (``guide_narrowed``) and those where it left none
        (``guide_fallbacks``)."""
        return {"solves": float(self.solves), "failures": float(self.failures),
                "guided": float(self.guided), "guide_narrowed": float(self.guide_narrowed),
                "guide_fallbacks": float(self.guide_fallbacks),
                "halts": float(self.halts),
                "halted": float(self.halt.state == Halt.STOPPING),
                "halt_since_s": self.halt_since_s,
                "halt_x": self.halt_xy[0], "halt_y": self.halt_xy[1]}


def _static_footholds(spec: str) -> list[Foothold]:
    """The footholds of a fixed source (``flat``), or [] for the channel's."""
    if spec == "flat":
        # one square with no edge within any run: 1 km each way is 45 min of walking (a 50 m
        # one ended long live runs: Cassie stepped in place at x = 50 m, its next footstep
        # clamped to the edge). The rows are unit normals, so the size costs the solve nothing.
        big = 1000.0
        return [
            Foothold.from_polygon(np.array([[-big, -big], [big, -big], [big, big], [-big, big]]))
        ]
    return []


def make_node(proc: ProcessConfig, profile: Profile, params: Params, gains: MpfcParams) -> Node:
    """Build the MPFC node from ``hw_config`` (gains file: Table V; params: sources)."""
    if profile.mode == "lockstep":
        # lockstep results must not depend on how busy the machine is: no wall-clock budget
        # (the search is finite: at most enumerate_max_leaves leaves, or the B&B tree)
        gains = dataclasses.replace(gains, time_limit_ms=math.inf)
    elif profile.rtf < 1.0:  # a slower machine running at a fraction of real time
        gains = dataclasses.replace(gains, time_limit_ms=gains.time_limit_ms / profile.rtf)
    solver: FootstepSolver | None = None
    if params.planner == "dcm":
        dcm = load(DcmParams, profile.resolve(params.dcm_gains))
        # its search's budget as the MPFC's above: none in lockstep, stretched below rtf 1
        budget = (math.inf if profile.mode == "lockstep"
                  else dcm.time_limit_ms / min(profile.rtf, 1.0))
        dcm = dataclasses.replace(dcm, variant=params.dcm_variant, time_limit_ms=budget)
        solver = DcmSolver(dcm, gains.mass_kg)
    guide = None
    if params.guide:
        if "guide" not in proc.inputs:
            raise ConfigError(str(proc.source_file), f"processes.{proc.name}.params.guide",
                              "true, but the process has no guide input",
                              allowed="false, or inputs: {guide: guide_plan} (the SLIP "
                                      "guide's plan, processes.slip_guide.process)")
        # the guide's regions for the MPFC's stance and its N footsteps
        guide = GuidedFootholds(gains.horizon_steps + 1, params.guide_margin_m,
                                params.guide_max_age_s, params.guide_max_speed_mps,
                                params.guide_long_step_m)
    return MpfcNode(
        gains,
        "channel" if params.footholds == "channel" else "static",
        _static_footholds(params.footholds),
        params.default_velocity,
        params.height_lookup,
        params.foothold_max_height_m,
        solver,
        guide,
    )
