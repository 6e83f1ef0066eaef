"""MpfcSolver: the public entry point the MPFC process calls once per new robot state.

Frames (as in the paper, Section III-A): the problem is posed in the stance frame, whose
origin is the current stance foot p_stance (world) and whose axes are the world axes turned
by `yaw` about z. The caller gives the ALIP state and the desired velocity in that frame;
footholds and returned footsteps are in the world frame. Returned ALIP states x_n are each
relative to footstep p_n, expressed in the stance frame's axes.

Timing: `t_remaining_s` is T*, the *nominal* time left in the current MPFC stance phase,
T_ss + T_ds - (time since touchdown) (Section IV and Fig. 4); the solution's
`t_remaining_opt_s` is the optimised T, i.e. the next touchdown is T seconds from now.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from processes.footstep_search.footholds import (
    FootholdCache,
    LocalFootholds,
    WorldFootholds,
    shifted_incumbent,
    yaw_rotation,
)
from processes.footstep_search.qp_engine import QpEngine
from processes.footstep_search.search import ExactSearch, SearchResult
from processes.mpfc.params import MpfcParams
from processes.mpfc.problem import MpfcModel, SolveInputs
from runtime.geometry import Foothold

STANCES = ("left", "right")


@dataclass
class Instance:
    """Arguments of one `MpfcSolver.solve` call."""

    x_alip: np.ndarray
    stance: str
    p_stance: np.ndarray
    t_remaining_s: float
    vdes: np.ndarray
    footholds: list[Foothold]
    yaw: float


@dataclass(frozen=True)
class SupportTransfer:
    """How support passed to the stance foot, for a planner whose model has no double stance
    (the DCM planner's): the previous stance foot (world), the time left in the double stance
    (0 once it is over) and its whole length; the OSC moves the centre of pressure from that
    foot to the stance foot over it ((2) of Acosta & Posa). The MPFC's ALIP model has its own
    ((28)) and ignores it."""

    prev_foot: np.ndarray
    left_s: float
    length_s: float


@dataclass
class MpfcSolution:
    """One MPFC solve. `footsteps` etc. are None unless `has_plan` (status optimal, or
    time_limited with an incumbent); on no plan the process keeps its previous one."""

    status: str  # 'optimal' | 'time_limited' | 'infeasible'
    footsteps: np.ndarray | None  # (N, 3) world positions of p_1..p_N
    foothold_indices: tuple[int, ...] | None  # indices into the `footholds` list given
    t_remaining_opt_s: float  # optimised T: time from now to the next touchdown
    first_stance_ss_duration_s: float  # total single-stance duration of the current stance
    ankle_torque_nm: float  # constant sagittal ankle torque u over the current stance
    alip_states: np.ndarray | None  # (N+1, 4) x_0..x_N of (15b)-(15c)
    objective: float
    solve_wall_ms: float
    optimizer_ms: float
    nodes_explored: int
    footholds_considered: int
    stance: str
    trust_region_active: bool = False
    lower_bound: float = field(default=float("nan"))

    @property
    def has_plan(self) -> bool:
        """True when footsteps, timing and torque are usable."""
        return self.footsteps is not None

    @classmethod
    def from_search(cls, res: SearchResult, lf: LocalFootholds, n: int, p_stance: np.ndarray,
                    rot: np.ndarray, stance: str, optimizer_ms: float,
                    trust_region_active: bool = False) -> MpfcSolution:
        """A footstep planner's solution from the exact search's result: status, bounds and,
        with an assignment, the ``n`` footsteps (``z[2:]`` in the stance frame) lifted onto
        their footholds' planes and put in the world. Timing, torque and states are the
        planner's to fill (NaN, None until then)."""
        sol = cls(
            status=res.status, footsteps=None, foothold_indices=None,
            t_remaining_opt_s=float("nan"), first_stance_ss_duration_s=float("nan"),
            ankle_torque_nm=float("nan"), alip_states=None, objective=res.objective,
            solve_wall_ms=0.0, optimizer_ms=optimizer_ms, nodes_explored=res.nodes,
            footholds_considered=lf.count, stance=stance,
            trust_region_active=trust_region_active, lower_bound=res.lower_bound)
        if res.z is not None and res.assignment is not None:
            steps_local = np.zeros((n, 3))
            steps_local[:, :2] = res.z[2:].reshape(n, 2)
            a = np.array(res.assignment)
            steps_local[:, 2] = lf.alpha[a] + np.einsum("nj,nj->n", lf.beta[a],
                                                        steps_local[:, :2])
            sol.footsteps = p_stance + steps_local @ rot.T
            sol.foothold_indices = tuple(int(i) for i in lf.index[a])
        return sol


def checked_inputs(who: str, recorder: list | None, x_alip: np.ndarray, stance: str,
                   p_stance: np.ndarray, t_remaining_s: float, vdes: np.ndarray,
                   footholds: list[Foothold], yaw: float
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """A footstep planner's solve inputs as arrays (x, p_stance, vdes, T*), recorded as an
    ``Instance`` when ``recorder`` is a list. A non-finite input has no optimum: a ValueError
    naming it at once (unchecked, the search spent its whole time budget on N = 2 and raised
    LinAlgError deep in the search on N = 3)."""
    if recorder is not None:
        recorder.append(Instance(
            np.array(x_alip, dtype=float), stance, np.array(p_stance, dtype=float),
            float(t_remaining_s), np.array(vdes, dtype=float), footholds, float(yaw)))
    if stance not in STANCES:
        raise ValueError(f"stance must be 'left' or 'right', got {stance!r}")
    x = np.asarray(x_alip, dtype=float).reshape(4)
    p = np.asarray(p_stance, dtype=float).reshape(3)
    v = np.asarray(vdes, dtype=float).reshape(2)
    t_star = float(t_remaining_s)
    for what, val in (("x_alip", x), ("p_stance", p), ("vdes", v), ("t_remaining_s", t_star),
                      ("yaw", float(yaw))):
        if not np.all(np.isfinite(val)):
            raise ValueError(f"{who}: {what} is not finite ({val})")
    return x, p, v, t_star


class MpfcSolver:
    """MPFC (15) solved to global optimality; keeps the previous solution between solves."""

    def __init__(self, params: MpfcParams) -> None:
        self.params = params
        self.model = MpfcModel(params)
        self.engine = QpEngine(params.horizon_steps, params.qp_eps_abs, params.qp_eps_rel)
        self.search = ExactSearch(self.engine, params.optimality_rel_tol,
                                  params.enumerate_max_leaves, params.search)
        self._footholds = FootholdCache(params.min_normal_z)
        self._prev: MpfcSolution | None = None
        self.last_inputs: SolveInputs | None = None  # for tests and debugging
        self.last_local: LocalFootholds | None = None
        self._prev_p_stance = np.zeros(3)
        #: when a list, every solve's arguments are appended to it as an ``Instance`` (to
        #: benchmark on the instances of a closed-loop run)
        self.recorder: list | None = None

    def reset(self) -> None:
        """Forget the previous solution (no incumbent, no trust region)."""
        self._prev = None

    def set_crossover_margin(self, margin_m: float) -> None:
        """The crossover rows' margin for the next solves (``crossover_margin_m`` by default;
        the node widens it while stepping to a stop, ``processes.mpfc.process``)."""
        self.model._hx[:] = -margin_m

    def _world_footholds(self, footholds: list[Foothold]) -> WorldFootholds:
        return self._footholds.world(footholds)

    def solve(
        self,
        x_alip: np.ndarray,
        stance: str,
        p_stance: np.ndarray,
        t_remaining_s: float,
        vdes: np.ndarray,
        footholds: list[Foothold],
        yaw: float = 0.0,
        transfer: SupportTransfer | None = None,
    ) -> MpfcSolution:
        """Solve (15) for the current state; see the module docstring for frames and timing.
        (``transfer`` is for planners without the ALIP's double stance: unused here.)"""
        t_start = time.perf_counter()
        p = self.params
        x_c, p_stance, v, t_star = checked_inputs("MpfcSolver.solve", self.recorder, x_alip,
                                                  stance, p_stance, t_remaining_s, vdes,
                                                  footholds, yaw)
        rot = yaw_rotation(yaw)
        world = self._world_footholds(footholds)
        lf = world.local(p_stance, yaw, p.foothold_max_count, p.foothold_max_distance_m,
                         p.foothold_anchor_m)
        prev = self._prev
        # same stance phase: same side, and the stance foot has not moved (a left-right-left
        # sequence with failed solves in between is a new phase)
        same_stance = (prev is not None and prev.stance == stance
                       and float(np.abs(p_stance - self._prev_p_stance).max()) < 0.05)
        trust_center = None
        trust_radius = 0.0
        if same_stance and t_star < p.trust_region_start_s:
            trust_center = (rot.T @ (prev.footsteps[0] - p_stance))[:2]
            trust_radius = max(p.trust_region_rate_mps * t_star, 0.0)
        inp = SolveInputs(x_c, t_star, v, -1.0 if stance == "left" else 1.0, trust_center,
                          trust_radius)
        self.last_inputs, self.last_local = inp, lf
        qp = self.model.condense(inp)
        incumbent = self._incumbent(prev, stance, lf) if prev is not None else None
        self.engine.optimizer_s = 0.0
        deadline = t_start + p.time_limit_ms * 1e-3
        res = self.search.run(qp, lf, incumbent, deadline)
        sol = MpfcSolution.from_search(res, lf, p.horizon_steps, p_stance, rot, stance,
                                       self.engine.optimizer_s * 1e3,
                                       trust_region_active=trust_center is not None)
        if sol.has_plan:
            z = res.z
            sol.t_remaining_opt_s = t_star + float(z[0])
            sol.first_stance_ss_duration_s = p.t_ss_s - t_star + sol.t_remaining_opt_s
            sol.ankle_torque_nm = float(z[1])
            sol.alip_states = qp.E @ z + qp.e
        sol.solve_wall_ms = (time.perf_counter() - t_start) * 1e3
        if sol.has_plan:
            self._prev = sol
            self._prev_p_stance = p_stance
        return sol

    def _incumbent(
        self, prev: MpfcSolution, stance: str, lf: LocalFootholds
    ) -> tuple[int, ...] | None:
        """Previous solve's foothold assignment, mapped to this solve's list
        (``footstep_search.footholds.shifted_incumbent``)."""
        return shifted_incumbent(prev.foothold_indices, prev.stance, stance, lf)
