"""DcmSolver: the DCM planner behind the MPFC's solver interface, so the footstep-planner
process runs either (``processes/mpfc/process.py``, ``params.planner``).

The process hands every planner the same things: the ALIP state about the stance contact
point in the stance frame (x = [x_com, y_com, L_x, L_y], Section III-A of Acosta & Posa), the
stance side and foot, T* (the nominal time left in the stance, double stance included) and the
desired velocity. The DCM of that state, for the ALIP with the CoM velocity L / (m H) (the
pendulum's, without the centroidal momentum), is

    xi = c + v / lambda  ->  xi_x = x_com + L_y / (m H lambda),  xi_y = y_com - L_x / (m H lambda)

and the step began t~ = T_nom - T* ago, so (23) gives the initial DCM z_1 = xi e^{-lambda t~}
(the stance foot at the origin; with the double stance's ramp below, plus kappa p_0).

In double stance the template's instant transfer of support at touchdown is not what the
robot does: the OSC moves the CoP from the previous stance foot p_0 to the stance foot along
a line over the double stance of length D ((2) of Acosta & Posa), and the CoM, started at
rest between Cassie's feet, is 13 cm outside the stance foot: a DCM there has no capture
within the stride bounds. So in double stance the DCM is first carried to the liftoff, r
seconds ahead, under that ramp (xi' = lambda (xi - p(t)), p linear: closed form below), and
that liftoff DCM is the template's at t~ = T_ds after its touchdown, the step's remaining
time T_1 - T_ds + r (ours: Xiang et al.'s Digit controller handles its double stance below
the planner). The planner's step-to-step map has the same ramp in it
(``processes.dcm_planner.problem.ramp_kappa``): after it, xi(t~) = e^{lambda t~} (z_1 - kappa
p_0), so z_1 = xi e^{-lambda t~} + kappa p_0, p_0 the previous stance foot. Cassie's step,
double stance included, is the template's step: T_k spans touchdown to touchdown.

The command sets the nominal stride of (14), v T_nom, and its goal, "a velocity-aligned
waypoint": walking periodically at v, the DCM at the start of step k lies (k - 1) strides
ahead plus the periodic offset stride / (sigma_nom - 1) (sagittal), so z_goal is the mean of
those over the stages k = 2..N+1 of (14): v T_nom ((N + 1) / 2) plus that offset. (A goal
farther ahead, the command's displacement over 4 steps, was tried: the DCM cost pulled the
walk to 0.79 m/s at a 0.375 m/s command, measured on flat ground.) No ankle torque (the DCM
template has none): the plan's is 0.
"""

from __future__ import annotations

import math
import time

import numpy as np

from processes.dcm_planner.params import DcmParams
from processes.dcm_planner.problem import DcmInputs, DcmModel
from processes.footstep_search.footholds import FootholdCache, shifted_incumbent, yaw_rotation
from processes.footstep_search.qp_engine import QpEngine
from processes.footstep_search.search import ExactSearch
from processes.mpfc.solver import MpfcSolution, SupportTransfer, checked_inputs
from runtime.geometry import Foothold


class DcmSolver:
    """(21) solved to global optimality by the shared search; keeps the previous solution."""

    def __init__(self, params: DcmParams, mass_kg: float = 33.3) -> None:
        self.params = params
        self.mass_kg = mass_kg
        self.model = DcmModel(params)
        self.engine = QpEngine(self.model.F, params.qp_eps_abs, params.qp_eps_rel)
        self.search = ExactSearch(self.engine, params.optimality_rel_tol,
                                  params.enumerate_max_leaves, params.search)
        self._footholds = FootholdCache(params.min_normal_z)
        self._prev: MpfcSolution | None = None
        self.last_inputs: DcmInputs | None = None  # for tests and debugging
        self.last_local = None
        self.recorder: list | None = None  # as MpfcSolver's

    def reset(self) -> None:
        """Forget the previous solution (no incumbent)."""
        self._prev = None

    def dcm_of(self, x_alip: np.ndarray) -> np.ndarray:
        """The DCM (relative to the stance foot, stance frame) of an ALIP state."""
        p = self.params
        mhl = self.mass_kg * p.com_height_m * p.lam
        return np.array([x_alip[0] + x_alip[3] / mhl, x_alip[1] - x_alip[2] / mhl])

    def _at_liftoff(self, xi: np.ndarray, ds: SupportTransfer, p0: np.ndarray) -> np.ndarray:
        """The DCM (stance frame) at the liftoff, ``ds.left_s`` ahead, the CoP moving on a
        line from the previous foot p0 to the stance foot, reached at the liftoff: for p(t) =
        p + p' t, xi(r) = p(r) + p'/lambda + (xi - p - p'/lambda) e^{lambda r}."""
        lam = self.params.lam
        rate = -p0 / max(ds.length_s, 1e-3)  # p' (stance frame); p(now) = -rate * left
        cop = -rate * ds.left_s
        return rate / lam + (xi - cop - rate / lam) * math.exp(lam * ds.left_s)

    def solve(self, x_alip: np.ndarray, stance: str, p_stance: np.ndarray,
              t_remaining_s: float, vdes: np.ndarray, footholds: list[Foothold],
              yaw: float = 0.0, transfer: SupportTransfer | None = None) -> MpfcSolution:
        """Plan from the ALIP state; see the module docstring for the frames and timing."""
        t_start = time.perf_counter()
        p = self.params
        x, p_stance, v, _ = checked_inputs("DcmSolver.solve", self.recorder, x_alip, stance,
                                           p_stance, t_remaining_s, vdes, footholds, yaw)
        rot = yaw_rotation(yaw)
        xi = self.dcm_of(x)
        kap = self.model.kappa
        p0 = (rot[:2, :2].T @ (np.asarray(transfer.prev_foot, dtype=float)[:2] - p_stance[:2])
              if transfer is not None else np.zeros(2))  # stance frame
        if transfer is not None and transfer.left_s > 0.0:
            # the DCM at the liftoff, the template's at T_ds (module docstring)
            z1 = self._at_liftoff(xi, transfer, p0) * math.exp(-p.lam * p.t_ds_s) + kap * p0
            elapsed = p.t_ds_s - transfer.left_s  # (< 0 in a start's longer one)
        else:
            elapsed = min(max(p.t_nom_s - float(t_remaining_s), 0.0), p.t_max_s)
            z1 = xi * math.exp(-p.lam * elapsed) + kap * p0  # (23), the ramp undone
        stride = v * p.t_nom_s
        goal = stride * 0.5 * (self.model.N + 1)
        sn = self.model.sigma_nom
        goal[0] += stride[0] * (1.0 - sn * kap) / (sn - 1.0)  # the periodic DCM offset
        inp = DcmInputs(z1, goal, float(stride[0]),
                        0 if stance == "left" else 1, p0)
        lf = self._footholds.world(footholds).local(
            p_stance, yaw, p.foothold_max_count, p.foothold_max_distance_m, p.foothold_anchor_m)
        self.last_inputs, self.last_local = inp, lf
        qp = self.model.condense(inp)
        prev = self._prev
        incumbent = (shifted_incumbent(prev.foothold_indices, prev.stance, stance, lf)
                     if prev is not None else None)
        self.engine.optimizer_s = 0.0
        res = self.search.run(qp, lf, incumbent, t_start + p.time_limit_ms * 1e-3)
        sol = MpfcSolution.from_search(res, lf, self.model.F, p_stance, rot, stance,
                                       self.engine.optimizer_s * 1e3)
        if sol.has_plan:
            z = res.z
            t1 = math.log(float(z[0])) / p.lam  # sigma_1 = e^{lambda T_1}
            sol.t_remaining_opt_s = max(t1 - elapsed, 0.0)
            sol.first_stance_ss_duration_s = t1
            sol.ankle_torque_nm = 0.0
            sol.alip_states = (np.einsum("kaz,z->ka", qp.E, z) + qp.e)[1:]  # z_1..z_{N+1}
        sol.solve_wall_ms = (time.perf_counter() - t_start) * 1e3
        if sol.has_plan:
            self._prev = sol
        return sol
