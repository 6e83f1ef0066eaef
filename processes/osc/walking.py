"""Walking outputs from an MPFC plan (Section V): gait phase, CoM height plane, swing foot.

* ``GaitPhase``: stance/swing and the liftoff/touchdown times from ``mpfc_output_t``.
* ``ComHeightPlane``: the least-inclined plane through the current and next footholds (21) and
  the CoM height reference (22), with the 100 Hz low-pass on (k_x, k_y) and the 2.5 cm clip.
* ``SwingFootTrajectory``: the adaptive-clearance midpoint (Section V-B-1) and the swing QP (23)
  as a polynomial with acceleration continuity to the previous tick's plan.
* ``WalkingController``: the task rows of Tables VI-VII for one tick, and the MPFC ankle torque
  as a cost (Section V-D).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numba
import numpy as np

from lcmtypes import mpfc_output_t

from .model import LEFT, RIGHT, CassieModel
from .qp import OscQP, TaskRows
from .tasks import (
    DOUBLE_STANCE_TASKS,
    SINGLE_STANCE_TASKS,
    TaskLog,
    WalkingParams,
    walking_rows,
)

_jit = numba.njit(cache=True, nogil=True)

# the gait phases of mpfc_output_t.gait_state (its consts: one list, in the message type)
SINGLE_LEFT, SINGLE_RIGHT = mpfc_output_t.GAIT_LEFT_SS, mpfc_output_t.GAIT_RIGHT_SS
DOUBLE_AFTER_LEFT = mpfc_output_t.GAIT_DS_AFTER_LEFT
DOUBLE_AFTER_RIGHT = mpfc_output_t.GAIT_DS_AFTER_RIGHT
STANDING = mpfc_output_t.GAIT_STANDING
_STANCE_MASKS = {
    LEFT: np.array([True, True, False, False]),
    RIGHT: np.array([False, False, True, True]),
    None: np.ones(4, dtype=bool),
}


@dataclass
class GaitPhase:
    """The gait state the OSC acts on at one tick."""

    stance: int  # 0 left, 1 right: the (current or upcoming) stance leg
    single_stance: bool  # False: double stance, both feet carry force
    liftoff_s: float  # start of the current swing (single stance)
    touchdown_s: float  # planned end of the current swing

    @staticmethod
    def from_plan(plan: Any, t: float) -> GaitPhase:
        """Read the phase from an ``mpfc_output_t``; past the planned touchdown the swing foot
        is treated as landed (double stance) until the next plan switches the stance."""
        gs = int(plan.gait_state)
        stance = int(plan.stance)
        lo = float(plan.prev_switch_time_s)
        td = float(plan.next_switch_time_s)
        single = gs in (SINGLE_LEFT, SINGLE_RIGHT) and t < td
        if gs in (SINGLE_LEFT, SINGLE_RIGHT):
            stance = LEFT if gs == SINGLE_LEFT else RIGHT
        return GaitPhase(stance, single, lo, td)


class ComHeightPlane:
    """CoM height reference on the plane through the current and next footholds, (21)-(22)."""

    def __init__(self, params: WalkingParams) -> None:
        self.p = params
        self.k = np.zeros(2)  # low-passed (k_x, k_y) (a copy of the float state below)
        self._kx = self._ky = 0.0
        self.t_last: float | None = None

    def reset(self) -> None:
        """Forget the filter state (a new walking episode)."""
        self.t_last = None
        self.k[:] = 0.0
        self._kx = self._ky = 0.0

    def reference(self, t: float, stance_pos: Any, next_pos: Any, yaw: float,
                  com: Any, com_vel: Any) -> tuple[float, float, float]:
        """Return (z_des, zdot_des, k_x) in the world frame for the current CoM state
        (positions as 3-sequences of floats, world frame)."""
        c, s = math.cos(yaw), math.sin(yaw)
        s0, s1, s2 = (float(x) for x in stance_pos)
        n0, n1, n2 = (float(x) for x in next_pos)
        d0, d1 = n0 - s0, n1 - s1
        px, py, pz = c * d0 + s * d1, -s * d0 + c * d1, n2 - s2  # stance frame
        det = px * px + py * py  # (21): [[px, py], [-py, px]] k = [pz, 0]
        if det > 1e-6:
            kx, ky = px * pz / det, py * pz / det
        else:
            kx = ky = 0.0
        # first-order low-pass with a com_filter_hz cutoff (Section V-A)
        if self.t_last is None:
            self._kx, self._ky = kx, ky
        else:
            dt = max(0.0, t - self.t_last)
            a = 1.0 - math.exp(-2.0 * math.pi * self.p.com_filter_hz * dt)
            self._kx += a * (kx - self._kx)
            self._ky += a * (ky - self._ky)
        self.t_last = t
        fx, fy = self._kx, self._ky
        self.k[0] = fx
        self.k[1] = fy
        c0, c1, c2 = (float(x) for x in com)
        r0, r1 = c0 - s0, c1 - s1
        xc, yc = c * r0 + s * r1, -s * r0 + c * r1
        vx, vy = c * com_vel[0] + s * com_vel[1], -s * com_vel[0] + c * com_vel[1]
        z = s2 + self.p.com_height + fx * xc + fy * yc  # (22)
        clip = self.p.com_clip  # keep z_des within 2.5 cm of the measured CoM height
        z = min(max(z, c2 - clip), c2 + clip)
        return z, fx * vx + fy * vy, fx


def swing_midpoint(p0: np.ndarray, p_des: np.ndarray, clearance: float) -> list[float]:
    """Adaptive-clearance waypoint of Section V-B-1 (Fig. 6), as [x, y, z].

    n_p is perpendicular to dp = p_des - p0 in the plane of dp and e_z; it is blended with e_z
    for short steps (s ramps from 0 at |dp| = 0.1 m to 1 at 0.2 m), and the clearance is
    c + min(c, dp_z). Float arithmetic: this runs every tick.
    """
    a = p0.tolist()
    b = p_des.tolist()
    dx, dy, dz = b[0] - a[0], b[1] - a[1], b[2] - a[2]
    n2 = dx * dx + dy * dy + dz * dz
    n = math.sqrt(n2)
    if n > 1e-9:
        k = dz / n2  # e_z minus its component along dp
        px, py, pz = -dx * k, -dy * k, 1.0 - dz * k
        nn = math.sqrt(px * px + py * py + pz * pz)
        px, py, pz = (px / nn, py / nn, pz / nn) if nn > 1e-9 else (0.0, 0.0, 1.0)
    else:
        px, py, pz = 0.0, 0.0, 1.0
    s = min(max((n - 0.1) / 0.1, 0.0), 1.0)
    bx, by, bz = s * px, s * py, (1.0 - s) + s * pz
    nb = math.sqrt(bx * bx + by * by + bz * bz)
    c = (clearance + min(clearance, dz)) / nb
    return [a[0] + 0.5 * dx + c * bx, a[1] + 0.5 * dy + c * by, a[2] + 0.5 * dz + c * bz]


def swing_waypoints(p0: np.ndarray, p_des: np.ndarray, clearance: float, step_up_min: float,
                    step_up_clearance: float, step_up_height: float, lift_tau: float,
                    approach_tau: float) -> list[tuple[float, list[float]]]:
    """The waypoints (tau, p) of one swing, tau in fractions of the swing time T.

    Below a rise or drop of ``step_up_min`` (and always when it is 0) this is the paper's
    adaptive midpoint at T/2 (Section V-B-1). Stepping up by more, three waypoints: the foot
    rises to
    ``step_up_height`` over the higher end straight above where it lifted off (at
    ``lift_tau``), crosses above the halfway point at ``step_up_clearance`` over the higher end
    (T/2), and is ``step_up_height`` straight above the target at ``approach_tau``. A step
    between the two ends can be anywhere from just ahead of the toe at lift-off to just
    behind the heel at touchdown (the footholds leave only a margin beyond the foot), so the
    foot must rise before it moves forward and stop moving forward before it descends. The
    paper's midpoint leans back along n_p, which clears the toe but brings the foot down
    diagonally onto the step's nosing (measured in MuJoCo on 15 cm stairs: the heel lands on
    the edge, 7 cm short of the target); a midpoint above halfway at c clears the heel but
    not the toe (the toe hits the next riser, measured), and c = 15 cm over a 30 cm rise
    folds the swing knee to its limit (measured). Stepping down as much, the same rise over the
    edge the foot stands on, then down over the target: the paper's clearance there is
    c + dz over the line between the ends, which passes below the edge right ahead of the toe
    (measured on stepping stones: a 12 cm step down from a stone's front edge caught the toe
    on it, the foot landed 28 cm short and the robot fell).
    """
    dz = float(p_des[2] - p0[2])
    if step_up_min <= 0.0 or abs(dz) < step_up_min:
        return [(0.5, swing_midpoint(p0, p_des, clearance))]
    a, b = p0.tolist(), p_des.tolist()
    top = max(a[2], b[2])
    return [
        (lift_tau, [a[0], a[1], top + step_up_height]),
        (0.5, [0.5 * (a[0] + b[0]), 0.5 * (a[1] + b[1]), top + step_up_clearance]),
        # stepping down, the foot comes down over the target from its own height above it
        (approach_tau, [b[0], b[1], (top if dz > 0.0 else b[2]) + step_up_height]),
    ]


#: a swing begun this long after its liftoff is a restart mid-swing (``SwingFootTrajectory.start``)
RESTART_S = 0.02


class SwingFootTrajectory:
    """Swing-foot polynomial from the QP (23), re-solved every tick.

    The polynomial is in normalised time tau = (t - t_liftoff) / T over the whole swing; (23)
    minimises the integral of the squared acceleration subject to continuity of position,
    velocity and acceleration with the previous tick's polynomial at the previous tick's time,
    the end conditions p(T) = p_des, p'(T) = p''(T) = 0, and p(T/2) = p_mid (dropped from
    0.1 T before mid-swing on, where it would nearly repeat the continuity row). Stepping up
    by ``step_up_min`` or more, the waypoints are those of ``swing_waypoints`` (one row each,
    each dropped likewise 0.1 T before its time). The equality-constrained KKT system is
    solved in closed form, one factorisation for 3 axes (compiled: ``_swing_solve``).
    """

    def __init__(self, degree: int = 8, freeze_s: float = 0.02, mid_margin: float = 0.1,
                 step_up_min: float = 0.0, step_up_clearance: float = 0.06,
                 step_up_height: float = 0.04, lift_tau: float = 0.25,
                 approach_tau: float = 0.8) -> None:
        self.deg = degree
        nc = degree + 1
        self.nc = nc
        self.step_up_min = step_up_min
        self.step_up_clearance = step_up_clearance
        self.step_up_height = step_up_height
        self.lift_tau = lift_tau
        self.approach_tau = approach_tau
        Q = np.zeros((nc, nc))
        for a in range(2, nc):
            for b in range(2, nc):
                Q[a, b] = a * (a - 1) * b * (b - 1) / (a + b - 3)  # int of tau^(a-2) tau^(b-2)
        self._Q2 = 2.0 * Q
        self.coef = np.zeros((nc, 3))
        self.T = 1.0
        self.t_prev = 0.0
        self.liftoff = 0.0
        self.p0 = np.zeros(3)
        self.active = False
        self.freeze_s = freeze_s
        self.mid_margin = mid_margin
        # scratch of the compiled KKT solve: waypoints (tau, x, y, z), KKT matrix and rhs
        self._wp = np.zeros((4, 4))
        self._K = np.zeros((nc + 6 + 4, nc + 6 + 4))
        self._rhs = np.zeros((nc + 6 + 4, 3))
        self._out = np.zeros((3, 3))
        # compile the kernels (or load them from numba's on-disk cache) now
        _swing_eval(self.coef, 0.0, 1.0, self._out)
        _swing_solve(self._Q2, np.zeros((nc, 3)), 0.0, 0.0, 1.0, np.zeros(3), self._wp, 1,
                     self._K, self._rhs)

    def start(self, t: float, liftoff: float, touchdown: float, p_now: np.ndarray,
              v_now: np.ndarray | None = None) -> None:
        """Begin a swing at the current foot position with zero velocity and acceleration.

        Started more than ``RESTART_S`` after the liftoff (the controller took the robot back
        mid-swing: after a safe-mode episode, a restart), the swing is planned afresh from
        now to the touchdown, from the foot's position and velocity ``v_now``. (Kept on the
        liftoff's time axis, the polynomial had to go from rest at the current point through
        the mid-swing waypoint a few tens of ms later: measured, the foot overshot its target
        by 0.19 m, the stance foot was dragged 0.15 m and the robot fell.)"""
        self.coef[:] = 0.0
        self.coef[0] = p_now
        self.p0 = p_now.copy()
        self.active = True
        if t - liftoff > RESTART_S:
            self.T = max(touchdown - t, 0.05)
            if v_now is not None:
                self.coef[1] = np.asarray(v_now) * self.T  # dp/dtau = T dp/dt
            self.liftoff = t
            self.t_prev = t
            return
        self.T = max(touchdown - liftoff, 0.05)
        tau = min(max((t - liftoff) / self.T, 0.0), 0.99)
        # the "previous plan" of the first tick: a constant at the initial foot position
        self.liftoff = liftoff
        self.t_prev = liftoff + tau * self.T

    def evaluate(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Position, velocity and acceleration of the current plan at time t (clamped to T)."""
        pos, vel, acc = self.evaluate_lists(t)
        return np.array(pos), np.array(vel), np.array(acc)

    def evaluate_lists(self, t: float) -> list[list[float]]:
        """``evaluate`` as three lists of floats [pos, vel, acc]."""
        return self.evaluate_into(t).tolist()

    def evaluate_into(self, t: float) -> np.ndarray:
        """``evaluate`` into a (3, 3) array [pos; vel; acc] owned by this object (the per-tick
        path: overwritten by the next call)."""
        tau = min(max((t - self.liftoff) / self.T, 0.0), 1.0)
        _swing_eval(self.coef, tau, self.T, self._out)
        return self._out

    def update(self, t: float, touchdown: float, p_des: np.ndarray, clearance: float) -> None:
        """Re-solve (23) for the newest touchdown time and target, then advance to t."""
        T_new = max(touchdown - self.liftoff, 0.05)
        remaining = T_new - (self.t_prev - self.liftoff)
        if remaining > self.freeze_s:
            # continuity with the previous tick's polynomial at the previous tick's time
            tau_prev = min(max((self.t_prev - self.liftoff) / self.T, 0.0), 1.0)
            tau_k = (self.t_prev - self.liftoff) / T_new
            # a waypoint near the current time would nearly repeat the continuity row p(tau_k)
            wp, n = self._wp, 0
            for tau, point in swing_waypoints(self.p0, p_des, clearance, self.step_up_min,
                                              self.step_up_clearance, self.step_up_height,
                                              self.lift_tau, self.approach_tau):
                if tau_k < tau - self.mid_margin:
                    wp[n, 0] = tau
                    wp[n, 1:] = point
                    n += 1
            # d/dtau_new = (T_new / T_old) d/dtau_old
            if _swing_solve(self._Q2, self.coef, tau_prev, tau_k, T_new / self.T, p_des, wp, n,
                            self._K, self._rhs) == 0:
                self.T = T_new
        self.t_prev = t


@_jit
def _basis_row(tau: float, d: int, out: np.ndarray) -> None:
    """Row ``d`` (0: p, 1: dp/dtau, 2: d2p/dtau2) of the monomials 1, tau, ..., tau^deg."""
    nc = out.size
    pw = 1.0  # tau^(i - d)
    for i in range(nc):
        if i < d:
            out[i] = 0.0
            continue
        f = 1.0 if d == 0 else (i if d == 1 else i * (i - 1))
        out[i] = f * pw
        pw *= tau


@_jit
def _swing_eval(coef: np.ndarray, tau: float, T: float, out: np.ndarray) -> None:
    """out = [p, dp/dt, d2p/dt2] (3, 3) of the polynomial ``coef`` (nc, 3) at tau (time T)."""
    nc = coef.shape[0]
    row = np.empty(nc)
    for d in range(3):
        _basis_row(tau, d, row)
        scale = 1.0 if d == 0 else (T if d == 1 else T * T)
        for a in range(3):
            s = 0.0
            for i in range(nc):
                s += row[i] * coef[i, a]
            out[d, a] = s / scale if d > 0 else s


@_jit
def _swing_solve(Q2: np.ndarray, coef: np.ndarray, tau_prev: float, tau_k: float, s: float,
                 p_des: np.ndarray, wp: np.ndarray, nwp: int, Kbuf: np.ndarray,
                 rbuf: np.ndarray) -> int:
    """One solve of (23): the KKT system [2Q A'; A 0] [c; nu] = [0; d] with A = [end rows
    p, p', p'' at tau = 1 (3); waypoint positions (nwp); continuity p, p', p'' at tau_k (3)]
    and d = [p_des, 0, 0; waypoints; the old polynomial at tau_prev, its derivatives scaled
    by s and s^2]; LU with partial pivoting, 3 right-hand sides. Writes ``coef`` (nc, 3) and
    returns 0, or 1 (``coef`` unchanged) when the system is singular."""
    nc = coef.shape[0]
    N = nc + 6 + nwp
    K = Kbuf[:N, :N]
    rhs = rbuf[:N]
    row = np.empty(nc)
    prev = np.zeros((3, 3))  # old polynomial at tau_prev: d/dtau_old
    for d in range(3):
        _basis_row(tau_prev, d, row)
        for a in range(3):
            for i in range(nc):
                prev[d, a] += row[i] * coef[i, a]
    # (explicit loops: slice assignments make numba compile far longer)
    for i in range(N):
        for j in range(N):
            K[i, j] = Q2[i, j] if i < nc and j < nc else 0.0
        for a in range(3):
            rhs[i, a] = 0.0
    for d in range(3):  # p(1) = p_des, p'(1) = p''(1) = 0
        _basis_row(1.0, d, row)
        for j in range(nc):
            K[nc + d, j] = row[j]
    for w in range(nwp):
        _basis_row(wp[w, 0], 0, row)
        for j in range(nc):
            K[nc + 3 + w, j] = row[j]
        for a in range(3):
            rhs[nc + 3 + w, a] = wp[w, 1 + a]
    r = nc + 3 + nwp
    for d in range(3):
        _basis_row(tau_k, d, row)
        for j in range(nc):
            K[r + d, j] = row[j]
    for i in range(nc, N):
        for j in range(nc):
            K[j, i] = K[i, j]
    for a in range(3):
        rhs[nc, a] = p_des[a]
    f = 1.0
    for d in range(3):
        for a in range(3):
            rhs[r + d, a] = prev[d, a] * f
        f = s if d == 0 else s * s
    # Gaussian elimination with partial pivoting (as LAPACK's dgesv)
    for k in range(N):
        piv = k
        big = abs(K[k, k])
        for i in range(k + 1, N):
            if abs(K[i, k]) > big:
                big = abs(K[i, k])
                piv = i
        if big == 0.0:
            return 1
        if piv != k:
            for j in range(N):
                K[k, j], K[piv, j] = K[piv, j], K[k, j]
            for a in range(3):
                rhs[k, a], rhs[piv, a] = rhs[piv, a], rhs[k, a]
        for i in range(k + 1, N):
            lik = K[i, k] / K[k, k]
            if lik != 0.0:
                for j in range(k + 1, N):
                    K[i, j] -= lik * K[k, j]
                for a in range(3):
                    rhs[i, a] -= lik * rhs[k, a]
    for i in range(N - 1, -1, -1):
        for a in range(3):
            t = rhs[i, a]
            for j in range(i + 1, N):
                t -= K[i, j] * rhs[j, a]
            rhs[i, a] = t / K[i, i]
    for i in range(nc):
        for a in range(3):
            coef[i, a] = rhs[i, a]
    return 0


class WalkingController:
    """Task rows for one walking tick from the newest MPFC plan (Tables VI-VII, Section V)."""

    def __init__(self, params: WalkingParams, nv: int) -> None:
        self.p = params
        self.plane = ComHeightPlane(params)
        self.swing = SwingFootTrajectory(params.swing_degree,
                                         step_up_min=params.swing_step_up_min,
                                         step_up_clearance=params.swing_step_up_clearance,
                                         step_up_height=params.swing_step_up_height,
                                         lift_tau=params.swing_lift_tau,
                                         approach_tau=params.swing_approach_tau)
        self._swing_key: tuple[int, float] | None = None
        self._zero3 = [0.0, 0.0, 0.0]
        self.phase: GaitPhase | None = None
        #: per-contact-point normal-force caps for the QP (inf: only the configured limit)
        self.fz_max = np.full(4, np.inf)
        #: per-contact-point normal-force floors (None: none beyond the QP's)
        self.fz_floor: np.ndarray | None = None
        self._floor = np.zeros(4)
        #: this walk began from the standing controller (``_double_stance``)
        self.from_standing = False
        self._start_t: float | None = None
        self._errs = np.zeros(len(SINGLE_STANCE_TASKS))
        # compile the kernel (or load it from numba's on-disk cache) now, not on the first tick
        kin, rows = np.zeros((20, 3)), np.zeros((16, 4))
        kin[0:3] = np.eye(3)
        kin[8:12] = ((0.1, 0.1, 0.0), (-0.1, 0.1, 0.0), (0.1, -0.1, 0.0), (-0.1, -0.1, 0.0))
        g = [x.packed for x in (params.com, params.pelvis, params.swing_foot, params.toe,
                                params.hip_yaw)]
        walking_rows(kin, np.zeros(12), np.zeros(nv + 3), np.zeros(nv),
                      np.zeros((16, 2), np.int64), rows, 0, self._errs, np.zeros((2, 12)), *g,
                      0.8, 0.0, 0.0, 0.0, True, 0, np.zeros((3, 3)), 0.0, 0, 0, True, -1.0)

    def _double_stance(self, qp: OscQP, m: CassieModel, plan: Any, t: float,
                       stance: int) -> float:
        """Weight transfer of the ALIP's double stance, f(t) = t / T_ds of (2) and (7): the
        trailing foot may carry at most (1 - f) m g, so it lifts off unloaded and its leaf
        springs do not ring through the swing (Section III-B), and the centre of pressure is
        pulled towards p_CoP(t) = p_- + f (p_+ - p_-) of (2), where the MPFC's reset map (9)
        assumes it is. Sets the caps and the moment cost; returns f when the CoP moment rows
        are wanted (``tasks.walking_rows`` writes them), else -1."""
        self.fz_max[:] = np.inf
        self.fz_floor = None
        if int(plan.gait_state) not in (DOUBLE_AFTER_LEFT, DOUBLE_AFTER_RIGHT):
            return -1.0  # a swing past its planned touchdown: both feet may carry the robot
        t0, t1 = float(plan.prev_switch_time_s), float(plan.next_switch_time_s)
        f = min(max((t - t0) / (t1 - t0), 0.0), 1.0) if t1 > t0 else 1.0
        trail = 1 - stance
        self.fz_max[2 * trail : 2 * trail + 2] = 0.5 * (1.0 - f) * m.mass * 9.81  # 2 points
        if self.from_standing and t1 - t0 > self.p.start_unload_s:
            # (ours) out of standing the CoP is between the feet and both legs' leaf springs
            # are loaded. The CoP target of (2) at f = 0 is the trailing foot: the leading
            # foot's planned force fell from 87 to 2 N a point in one tick, its springs let go
            # and lifted it 2-3 cm while the QP still counted on it, and it slid 2-23 cm
            # inward within 0.15 s (measured after 0.05-1.0 s of standing, ground truth and
            # perception alike; the start at the first tick, with no standing, never did).
            # So it keeps at least its standing share, unloaded to ``start_fz_min`` over
            # ``start_unload_s``: the CoP follows (2) as far as that allows. Only in a double
            # stance longer than that, the MPFC's weight shift from rest
            # (``GaitClock.from_standing``): one of T_ds ends before the floor comes off.
            if self._start_t is None:
                self._start_t = t
            p = self.p
            left = 1.0 - (t - self._start_t) / p.start_unload_s if p.start_unload_s > 0 else 0.0
            share = 0.25 * m.mass * 9.81 * left
            self._floor[:] = 0.0
            self._floor[2 * stance : 2 * stance + 2] = max(p.start_fz_min, share)
            self.fz_floor = self._floor
        if self.p.ankle_torque_weight > 0.0:
            qp.moment_target[0] = qp.moment_target[1] = 0.0
            qp.moment_count = 2
            qp.moment_weight = self.p.ankle_torque_weight
            return f
        return -1.0

    def reset(self, from_standing: bool = False) -> None:
        """Start a new walking episode: filters and swing plan from scratch;
        ``from_standing``: out of the standing controller (``_double_stance``)."""
        self.plane.reset()
        self._swing_key = None
        self.swing.active = False
        self.from_standing = from_standing
        self.fz_floor = None
        self._start_t = None

    def add_tasks(self, rows: TaskRows, log: TaskLog, qp: OscQP, m: CassieModel, q: np.ndarray,
                  v: np.ndarray, t: float, plan: Any, ph: GaitPhase,
                  yaw_rate: float) -> np.ndarray:
        """Append the walking tasks for the plan's phase ``ph`` (``GaitPhase.from_plan``);
        return the stance-point mask. The references are computed here, the rows by the
        compiled ``tasks.walking_rows``."""
        p = self.p
        self.phase = ph
        st = ph.stance
        sw = 1 - st
        stance_pos = [float(x) for x in plan.stance_foot_world]
        next_pos = [float(x) for x in plan.next_footstep_world]
        yaw = float(plan.stance_yaw)

        # CoM height on the footstep plane (21)-(22), z only (Table VII weights x, y = 0).
        z, zd, kx = self.plane.reference(t, stance_pos, next_pos, yaw, m.com_l, m.com_vel_l)

        qp.moment_count = 0
        if ph.single_stance:
            self.from_standing = False  # (its first double stance is over)
            self.fz_floor = None
        else:
            self._swing_key = None
            cop_f = self._double_stance(qp, m, plan, t, st)
            rows.n = walking_rows(m.kin, m.Jc_dot_v, m.q, m.v, rows.ri, rows.rf, rows.n,
                                   self._errs, qp.moment_rows, p.com.packed, p.pelvis.packed,
                                   p.swing_foot.packed, p.toe.packed, p.hip_yaw.packed, z, zd,
                                   yaw_rate, yaw, False, st, self.swing._out, 0.0, 0, 0, False,
                                   cop_f)
            log.names.extend(DOUBLE_STANCE_TASKS)
            log.errors.extend(self._errs[:2].tolist())
            return _STANCE_MASKS[None]
        self.fz_max[:] = np.inf

        # Swing foot: trajectory from (23), restarted at each new liftoff.
        key = (sw, round(ph.liftoff_s, 4))
        if key != self._swing_key:
            self._swing_key = key
            self.swing.start(t, ph.liftoff_s, ph.touchdown_s, m.foot_center(sw),
                             m.foot_center_vel(sw))
        self.swing.update(t, ph.touchdown_s, np.array(next_pos), p.swing_clearance)
        ref = self.swing.evaluate_into(t)
        # Swing toe: foot at atan(k_x) to the horizontal (Section V-C), or level ("level": on
        # level footholds, where atan(k_x) would land the heel first, L/2 sin(atan k_x) ~ 3 cm
        # below the foot's centre on 15 cm stairs); swing hip yaw at zero (Section V-C).
        toe = math.atan(kx) if p.swing_toe == "plane" else 0.0
        # Ankle torque cost (Section V-D). The MPFC's u is the torque the ground applies to
        # the robot about the stance contact point, along the stance frame's y axis: the ALIP
        # state is about that point, so u = 0 must put the centre of pressure there (a cost
        # on the toe motor instead would put it under the toe joint, ~2 cm along the blade,
        # and push the robot forward every step).
        ankle = p.ankle_torque_weight > 0.0
        rows.n = walking_rows(m.kin, m.Jc_dot_v, m.q, m.v, rows.ri, rows.rf, rows.n, self._errs,
                               qp.moment_rows, p.com.packed, p.pelvis.packed,
                               p.swing_foot.packed, p.toe.packed, p.hip_yaw.packed, z, zd,
                               yaw_rate, yaw, True, st, ref, toe, int(m.hip_yaw_qpos[sw]),
                               int(m.hip_yaw_dof[sw]), ankle, -1.0)
        log.names.extend(SINGLE_STANCE_TASKS)
        log.errors.extend(self._errs.tolist())
        if ankle:
            qp.moment_target[0] = float(plan.ankle_torque)
            qp.moment_count = 1
            qp.moment_weight = p.ankle_torque_weight
        return _STANCE_MASKS[st]


__all__ = [
    "LEFT",
    "RIGHT",
    "ComHeightPlane",
    "GaitPhase",
    "SwingFootTrajectory",
    "WalkingController",
    "swing_midpoint",
    "swing_waypoints",
]
