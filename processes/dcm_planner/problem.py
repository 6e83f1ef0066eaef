"""The variable-timing DCM footstep MIQP of Xiang et al. (Section III, eqs. (8)-(21)), posed for
the shared exact search (``processes.footstep_search``) and, literally, for Gurobi.

Frame: the current stance foot's (p_1 = 0, axes turned by the stance yaw). Steps k = 1..N; p_1
is the stance foot, p_2..p_N the footsteps the search assigns footholds to; z_k = xi_{0,k} is
the DCM at the start of step k, z_1 given (backward-propagated from the measured DCM, (23)).

With sigma_k = e^{lambda T_k}, only the first step's timing free and the others nominal (20),
the step-to-step dynamics (8)/(12) are affine in the decision z = [sigma_1, 0, p_2, ..., p_N]:

    z_2 = sigma_1 z_1 + (1 - sigma_1) p_1 = sigma_1 z_1                (p_1 = 0)
    z_{k+1} = sigma_nom z_k + (1 - sigma_nom) p_k                     k = 2..N

with, for Cassie, the double stance's CoP ramp from p_{k-1} to p_k added (``ramp_kappa``;
ours, off with t_ds_s = 0),

(the second entry of z is unused, held at 0 by its bounds: the search's variable layout has
two continuous variables before the footsteps). Cost (14) with the stride slacks (10)-(11)
written out; hard rows: the inner-side lateral corridor (15), the sagittal capturability
bound (16), the DCM growth bound (17) and the stride boxes (19); the timing bounds (13) are
bounds on sigma_1; region membership (18) is the search's foothold rows (big-M and binaries
in the literal form, ``build_miqp``). (15) and (16) at k = 1 hold only data (z_1, p_1): they
are not decisions, so the QP leaves them out and ``DcmInputs.start_violations`` reports them.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from processes.dcm_planner.params import DcmParams
from processes.footstep_search.footholds import LocalFootholds
from processes.footstep_search.miqp import MiqpData
from processes.footstep_search.qp_engine import CondensedQp


@dataclass
class DcmInputs:
    """One solve's data in the stance frame."""

    z1: np.ndarray  # initial DCM of the current step (2,), (23)
    goal: np.ndarray  # z_goal of (14) (2,)
    stride_x: float  # p_nom^x of (14)
    ell: int  # stance sign of (11)/(15): 0 left stance, 1 right stance
    #: p_0, the previous stance foot (2,): where the double stance's CoP ramp starts
    p0: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(2))

    def start_violations(self, p: DcmParams) -> list[str]:
        """(15) and (16) at k = 1, which no decision can change: what fails, if anything."""
        out = []
        side = 1.0 if self.ell == 1 else -1.0  # (-1)^(1 + ell)
        if side * self.z1[1] < p.delta_y_m:
            out.append("(15) the DCM is not on the inner side of the stance foot")
        if abs(self.z1[0]) > sagittal_bound(p):
            out.append("(16) the DCM is past the sagittal capturability bound")
        return out


def ramp_kappa(p: DcmParams) -> float:
    """kappa of the double stance's CoP ramp (ours; 0 with t_ds_s = 0: the paper's template).

    The OSC moves the CoP from p_{k-1} to p_k on a line over the first T_ds of step k, where
    the template has it at p_k from the touchdown. Integrating xi' = lambda (xi - p(t)) over
    the step then gives

        z_{k+1} = sigma_k (z_k - kappa (p_{k-1} - p_k)) + (1 - sigma_k) p_k,
        kappa = lambda int_0^D e^{-lambda s} (1 - s / D) ds = 1 - (1 - e^{-lambda D}) / (lambda D),

    still affine in the footsteps (sigma_k nominal for k >= 2; p_0 is data at k = 1). Left
    out, the template under-predicted each step's DCM growth by about kappa times the stride
    (0.15 x 15 cm), and the planner's walk ran at 0.64 m/s for a 0.375 m/s command (measured
    on flat ground)."""
    x = p.lam * p.t_ds_s
    return 0.0 if x < 1e-9 else 1.0 - (1.0 - math.exp(-x)) / x


def sagittal_bound(p: DcmParams) -> float:
    """The right side of (16): L_max / (sigma_min - 1) - Delta_x."""
    return p.l_max_m / (math.exp(p.lam * p.t_min_s) - 1.0) - p.delta_x_m


class DcmModel:
    """Builds (21) for one solve: ``condense`` (the search's form), ``build_miqp`` (literal)."""

    def __init__(self, params: DcmParams) -> None:
        self.params = params
        self.N = params.steps  # steps of the preview, the current one included
        self.F = self.N - 1  # footsteps to place: p_2..p_N
        self.nz = 2 + 2 * self.F
        lam = params.lam
        self.sigma_nom = math.exp(lam * params.t_nom_s)
        self.kappa = ramp_kappa(params)
        if params.fixed_timing:
            self.sigma_lo = self.sigma_hi = self.sigma_nom
        else:
            self.sigma_lo = math.exp(lam * params.t_min_s)
            self.sigma_hi = math.exp(lam * params.t_max_s)

    def _sel(self, k: int) -> np.ndarray:
        """(2, nz) picking p_k out of z (zeros for p_1, the stance foot at the origin)."""
        s = np.zeros((2, self.nz))
        if k >= 2:
            s[:, 2 + 2 * (k - 2): 4 + 2 * (k - 2)] = np.eye(2)
        return s

    def states(self, z1: np.ndarray, p0: np.ndarray = np.zeros(2)  # noqa: B008 (read only)
               ) -> tuple[np.ndarray, np.ndarray]:
        """z_k = E[k] z + e[k] for k = 1..N+1 (index 0 unused): (N+2, 2, nz), (N+2, 2)."""
        n, sn, kap = self.N, self.sigma_nom, self.kappa
        e_mat = np.zeros((n + 2, 2, self.nz))
        e_vec = np.zeros((n + 2, 2))
        e_vec[1] = z1
        # z_2 = sigma_1 (z_1 - kappa p_0) (12 with the ramp, ``ramp_kappa``), p_1 = 0
        e_mat[2][:, 0] = z1 - kap * np.asarray(p0, dtype=float)
        for k in range(2, n + 1):
            e_mat[k + 1] = (sn * e_mat[k] - sn * kap * self._sel(k - 1)
                            + (sn * kap + 1.0 - sn) * self._sel(k))
            e_vec[k + 1] = sn * e_vec[k]
        return e_mat, e_vec

    def _stride_rows(self, k: int, ell: int) -> tuple[np.ndarray, np.ndarray]:
        """(10)-(11): s_k^x = a_x z and s_k^y = a_y z, k = 1..N-1."""
        d = self._sel(k + 1) - self._sel(k)
        sign = (-1.0) ** (k + ell)
        return d[0], sign * d[1]

    def condense(self, inp: DcmInputs) -> CondensedQp:
        """(21) in the search's form: 0.5 z'Pz + q'z + const, hard rows Gx z <= hx."""
        p, n, nz = self.params, self.N, self.nz
        e_mat, e_vec = self.states(np.asarray(inp.z1, dtype=float), inp.p0)
        pm = np.zeros((nz, nz))
        qv = np.zeros(nz)
        const = 0.0
        goal = np.asarray(inp.goal, dtype=float)
        for k in range(2, n + 2):  # DCM tracking of (14)
            r = e_vec[k] - goal
            pm += 2.0 * p.w_goal * e_mat[k].T @ e_mat[k]
            qv += 2.0 * p.w_goal * e_mat[k].T @ r
            const += p.w_goal * float(r @ r)
        # timing of (14): only sigma_1 is free, the others are nominal (20)
        pm[0, 0] += 2.0 * p.w_sigma
        qv[0] -= 2.0 * p.w_sigma * self.sigma_nom
        const += p.w_sigma * self.sigma_nom**2
        pm[1, 1] += 1.0  # the unused variable (bounds 0): keeps the (sigma_1, 0) block regular
        for k in range(1, n):  # stride slacks of (14)
            ax, ay = self._stride_rows(k, inp.ell)
            for a, w, nom in ((ax, p.w_stride_x, inp.stride_x),
                              (ay, p.w_stride_y, p.nominal_width_m)):
                pm += 2.0 * w * np.outer(a, a)
                qv -= 2.0 * w * nom * a
                const += w * nom**2
        rows, rhs = self._hard_rows(inp, e_mat, e_vec)
        z_lo = np.full(nz, -np.inf)
        z_hi = np.full(nz, np.inf)
        z_lo[0], z_hi[0] = self.sigma_lo, self.sigma_hi  # (13)
        z_lo[1] = z_hi[1] = 0.0
        return CondensedQp(pm, qv, const, np.zeros((0, nz)), np.zeros(0), np.zeros(0), 0.0,
                           rows, rhs, z_lo, z_hi, e_mat, e_vec, self.prefilter(inp))

    def _hard_rows(self, inp: DcmInputs, e_mat: np.ndarray, e_vec: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray]:
        """(15)-(17) (not in the variant D) and (19) as rows G z <= h."""
        p, n = self.params, self.N
        rows: list[np.ndarray] = []
        rhs: list[float] = []
        if p.viability:
            bound = sagittal_bound(p)
            for k in range(2, n + 1):
                sk = self._sel(k)
                side = (-1.0) ** (k + inp.ell)
                # (15): side (z_k^y - p_k^y) >= Delta_y
                rows.append(-side * (e_mat[k][1] - sk[1]))
                rhs.append(-p.delta_y_m + side * e_vec[k][1])
                # (16): |z_k^x - p_k^x| <= L_max / (sigma_min - 1) - Delta_x
                for sgn in (1.0, -1.0):
                    rows.append(sgn * (e_mat[k][0] - sk[0]))
                    rhs.append(bound - sgn * e_vec[k][0])
            for k in range(1, n):  # (17): z_{k+1}^x - z_k^x <= L_max
                rows.append(e_mat[k + 1][0] - e_mat[k][0])
                rhs.append(p.l_max_m - (e_vec[k + 1][0] - e_vec[k][0]))
            if inp.stride_x > 0.0 and math.isfinite(p.dcm_behind_max_m):
                for k in range(2, n + 1):  # (16'), ours: z_k^x - p_k^x >= -behind_max
                    sk = self._sel(k)
                    rows.append(-(e_mat[k][0] - sk[0]))
                    rhs.append(p.dcm_behind_max_m + e_vec[k][0])
        for k in range(1, n):  # (19)
            ax, ay = self._stride_rows(k, inp.ell)
            rows += [ax, -ax, ay, -ay]
            rhs += [p.l_max_m, -p.l_min_m, p.w_max_m, -p.w_min_m]
        return np.array(rows).reshape(-1, self.nz), np.array(rhs)

    def prefilter(self, inp: DcmInputs):
        """The stride boxes (19) as vertex tests: a footstep's polygon must hold some point a
        stride from some point of the previous step's (p_1: the origin)."""
        p = self.params

        def masks(qp: CondensedQp, lf: LocalFootholds
                  ) -> tuple[np.ndarray, list[np.ndarray]]:
            tol = 1e-9
            x, y = lf.V[:, :, 0], lf.V[:, :, 1]
            xmin, xmax, ymin, ymax = x.min(1), x.max(1), y.min(1), y.max(1)

            def ok(k: int, x0: np.ndarray, x1: np.ndarray, y0: np.ndarray, y1: np.ndarray,
                   j: slice | None = None) -> np.ndarray:
                # stride k from footholds [x0, x1] x [y0, y1] to each foothold (columns)
                sign = (-1.0) ** (k + inp.ell)
                dx_hi = xmax[None, :] - x0[:, None]
                dx_lo = xmin[None, :] - x1[:, None]
                dy_a = sign * (ymax[None, :] - y0[:, None])
                dy_b = sign * (ymin[None, :] - y1[:, None])
                dy_hi, dy_lo = np.maximum(dy_a, dy_b), np.minimum(dy_a, dy_b)
                return ((dx_hi >= p.l_min_m - tol) & (dx_lo <= p.l_max_m + tol)
                        & (dy_hi >= p.w_min_m - tol) & (dy_lo <= p.w_max_m + tol))

            zero = np.zeros(1)
            first = ok(1, zero, zero, zero, zero)[0]
            pairs = [ok(k, xmin, xmax, ymin, ymax) for k in range(2, self.N)]
            return first, pairs

        return masks

    def build_miqp(self, inp: DcmInputs, lf: LocalFootholds) -> MiqpData:
        """(21) literally, for the reference solvers: v = [z_1..z_{N+1} (2 each), p_1..p_N (2
        each), sigma_1, s^x_1..s^x_{N-1}, s^y_1..s^y_{N-1}], binaries delta_kj for p_2..p_N,
        big-M region rows (18). Its optimum equals ``condense``'s over all assignments."""
        p, n, m = self.params, self.N, lf.count
        iz, ip = 0, 2 * (n + 1)
        i_sig = ip + 2 * n
        isx = i_sig + 1
        isy = isx + (n - 1)
        nv = isy + (n - 1)

        def zk(k: int) -> slice:
            return slice(iz + 2 * (k - 1), iz + 2 * k)

        def pk(k: int) -> slice:
            return slice(ip + 2 * (k - 1), ip + 2 * k)

        sn, kap = self.sigma_nom, self.kappa
        z1 = np.asarray(inp.z1, dtype=float)
        p0 = np.asarray(inp.p0, dtype=float)
        aeq, beq = [], []

        def eq(cols: list[tuple[int, float]], b: float) -> None:
            row = np.zeros(nv)
            for c, v in cols:
                row[c] += v
            aeq.append(row)
            beq.append(b)

        for a in range(2):
            eq([(zk(1).start + a, 1.0)], float(z1[a]))  # z_1 given
            eq([(pk(1).start + a, 1.0)], 0.0)  # p_1 at the origin
            # (12) k = 1: z_2 = sigma_1 (z_1 - kappa (p_0 - p_1)) + (1 - sigma_1) p_1, p_1 = 0
            eq([(zk(2).start + a, 1.0), (i_sig, -float(z1[a] - kap * p0[a]))], 0.0)
            for k in range(2, n + 1):  # (12) k >= 2 with sigma_k = sigma_nom (20), the ramp
                eq([(zk(k + 1).start + a, 1.0), (zk(k).start + a, -sn),
                    (pk(k - 1).start + a, sn * kap),
                    (pk(k).start + a, -(sn * kap + 1.0 - sn))], 0.0)
        for k in range(1, n):  # (10), (11)
            sign = (-1.0) ** (k + inp.ell)
            eq([(isx + k - 1, 1.0), (pk(k + 1).start, -1.0), (pk(k).start, 1.0)], 0.0)
            eq([(isy + k - 1, 1.0), (pk(k + 1).start + 1, -sign), (pk(k).start + 1, sign)],
               0.0)
        pm = np.zeros((nv, nv))
        qv = np.zeros(nv)
        const = 0.0
        goal = np.asarray(inp.goal, dtype=float)
        for k in range(2, n + 2):  # (14)
            sl = zk(k)
            pm[sl, sl] += 2.0 * p.w_goal * np.eye(2)
            qv[sl] -= 2.0 * p.w_goal * goal
            const += p.w_goal * float(goal @ goal)
        pm[i_sig, i_sig] += 2.0 * p.w_sigma
        qv[i_sig] -= 2.0 * p.w_sigma * sn
        const += p.w_sigma * sn**2
        for k in range(1, n):
            for idx, w, nom in ((isx + k - 1, p.w_stride_x, inp.stride_x),
                                (isy + k - 1, p.w_stride_y, p.nominal_width_m)):
                pm[idx, idx] += 2.0 * w
                qv[idx] -= 2.0 * w * nom
                const += w * nom**2
        g_rows, gmu_rows, h = [], [], []

        def ineq(cols: list[tuple[int, float]], b: float, mu: np.ndarray | None = None
                 ) -> None:
            row = np.zeros(nv)
            for c, v in cols:
                row[c] += v
            g_rows.append(row)
            gmu_rows.append(np.zeros((n - 1) * m) if mu is None else mu)
            h.append(b)

        if p.viability:
            bound = sagittal_bound(p)
            for k in range(2, n + 1):
                side = (-1.0) ** (k + inp.ell)
                ineq([(zk(k).start + 1, -side), (pk(k).start + 1, side)], -p.delta_y_m)  # (15)
                for sgn in (1.0, -1.0):  # (16)
                    ineq([(zk(k).start, sgn), (pk(k).start, -sgn)], bound)
            for k in range(1, n):  # (17)
                ineq([(zk(k + 1).start, 1.0), (zk(k).start, -1.0)], p.l_max_m)
            if inp.stride_x > 0.0 and math.isfinite(p.dcm_behind_max_m):
                for k in range(2, n + 1):  # (16'), ours
                    ineq([(zk(k).start, -1.0), (pk(k).start, 1.0)], p.dcm_behind_max_m)
        lb = np.full(nv, -np.inf)
        ub = np.full(nv, np.inf)
        lb[i_sig], ub[i_sig] = self.sigma_lo, self.sigma_hi  # (13)
        lb[isx: isx + n - 1], ub[isx: isx + n - 1] = p.l_min_m, p.l_max_m  # (19)
        lb[isy: isy + n - 1], ub[isy: isy + n - 1] = p.w_min_m, p.w_max_m
        big = p.big_m_m
        for k in range(2, n + 1):  # (18)
            for j in range(m):
                mu = np.zeros((n - 1) * m)
                mu[(k - 2) * m + j] = big
                real = np.isfinite(lf.c[j])
                for a_row, b_val in zip(lf.F[j][real], lf.c[j][real], strict=True):
                    ineq([(pk(k).start, float(a_row[0])), (pk(k).start + 1, float(a_row[1]))],
                         float(b_val) + big, mu)
        smu = np.zeros((n - 1, (n - 1) * m))
        for k in range(n - 1):
            smu[k, k * m: (k + 1) * m] = 1.0
        return MiqpData(pm, qv, const, np.array(aeq), np.array(beq), np.array(g_rows),
                        np.array(gmu_rows), np.array(h), smu, lb, ub, n - 1, m, pk(2).start,
                        i_sig, i_sig, p.t_nom_s)
