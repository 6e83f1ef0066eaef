"""The MPFC problem (15)-(20), built two ways from the same inputs.

* `MpfcModel.condense` gives the form the exact search uses: the ALIP states are eliminated
  through (15b)/(15c), leaving z = [T - T*, u, p_1xy, ..., p_Nxy] and a QP per foothold
  assignment (footstep height drops out: it enters no cost and no dynamics).
* `build_miqp` gives the paper's mixed-integer program literally: explicit states x_0..x_N,
  3D footsteps, slack variables for the soft CoM limits, one binary per foothold per step and
  the big-M rows (20). The Gurobi backend and the reference enumeration in the tests use it.

Frames: everything is in the stance frame, origin at the current stance foot p_0, axes the
world axes turned by the robot's yaw. x_n is the ALIP state at the end of stance n, relative
to footstep p_n, expressed in that frame; p_0 = 0.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from processes.footstep_search.footholds import LocalFootholds
from processes.footstep_search.miqp import MiqpData
from processes.footstep_search.qp_engine import CondensedQp
from processes.mpfc.alip import AlipModel, VelocitySubspace
from processes.mpfc.params import MpfcParams


@dataclass
class SolveInputs:
    """Per-solve inputs in the stance frame (see the module docstring for the frame)."""

    x_c: np.ndarray  # current ALIP state (4,)
    t_nominal: float  # T*: nominal remaining time of the current stance phase, s
    v_des: np.ndarray  # desired velocity in the stance frame (2,), m/s
    sigma0: float  # sigma of (18) for the current stance: -1 left, +1 right
    trust_center: np.ndarray | None  # previous p_1 (xy) in this frame, or None
    trust_radius: float  # half-width of the trust-region box, m


def crossover_trust_masks(qp: CondensedQp, lf: LocalFootholds
                          ) -> tuple[np.ndarray, list[np.ndarray]]:
    """The MPFC's vertex tests (``CondensedQp.prefilter``): necessary conditions for a leaf to
    be feasible. Step 1 must reach the crossover side and the trust-region box; each later
    step must be able to lie on its crossover side of the previous one. Returns (ok_first
    (M,), ok_pair[k] (M, M))."""
    n = len(qp.hx)  # one crossover row per step
    tol = 1e-9
    y = lf.V[:, :, 1]
    ymin, ymax = y.min(axis=1), y.max(axis=1)
    # crossover row k: gx[k] z <= hx[k] with gx = -sigma_k (y_{k+1} - y_k)
    sig = -qp.Gx[:, 3]  # coefficient of p_1y is -sigma_0
    ok = np.where(sig[0] > 0, sig[0] * ymax >= -qp.hx[0] - tol,
                  sig[0] * ymin >= -qp.hx[0] - tol)
    lo, hi = qp.z_lo[2:4], qp.z_hi[2:4]
    if np.all(np.isfinite(lo)) and np.all(np.isfinite(hi)):
        x = lf.V[:, :, 0]
        ok &= (x.max(axis=1) >= lo[0] - tol) & (x.min(axis=1) <= hi[0] + tol)
        ok &= (ymax >= lo[1] - tol) & (ymin <= hi[1] + tol)
        corners = np.array([[lo[0], lo[1]], [lo[0], hi[1]], [hi[0], lo[1]], [hi[0], hi[1]]])
        ok &= np.all((lf.F @ corners.T).min(axis=2) <= lf.c + tol, axis=1)
    pairs = []
    for k in range(1, n):
        s_k = -qp.Gx[k, 3 + 2 * k]  # sigma_k, the coefficient of p_{k+1,y}
        hi_j = np.where(s_k > 0, s_k * ymax, s_k * ymin)  # max over P_j of sigma y
        lo_i = np.where(s_k > 0, s_k * ymin, s_k * ymax)  # min over P_i of sigma y
        pairs.append(hi_j[None, :] - lo_i[:, None] >= -qp.hx[k] - tol)
    return ok, pairs


class MpfcModel:
    """Everything constant for one parameter set: ALIP matrices, Appendix B subspace, and the
    parts of the condensed QP that do not change between solves."""

    def __init__(self, params: MpfcParams) -> None:
        self.params = params
        p = params
        self.alip = AlipModel.build(
            p.mass_kg, p.com_height_m, p.gravity_mps2, p.t_ss_s, p.t_ds_s,
            p.lateral_instant_transfer,
        )
        self.vs = VelocitySubspace.build(self.alip)
        n = p.horizon_steps
        self.N = n
        self.nz = 2 + 2 * n
        a_s, b_s = self.alip.A_s2s, self.alip.B_s2s[:, :2]
        self.Phi = np.stack([np.linalg.matrix_power(a_s, k) for k in range(n + 1)])
        # E_const: x_n dependence on u and footsteps; the tau column depends on x_c (per solve).
        self.sel = np.zeros((n + 1, 2, self.nz))  # sel[k] z = p_k (xy); p_0 = 0
        for k in range(1, n + 1):
            self.sel[k, :, 2 + 2 * (k - 1): 4 + 2 * (k - 1)] = np.eye(2)
        self.E_const = np.zeros((n + 1, 4, self.nz))
        for k in range(1, n + 1):
            self.E_const[k] = a_s @ self.E_const[k - 1] + b_s @ (self.sel[k] - self.sel[k - 1])
        q_run = np.diag(p.q_running)
        q_term = np.diag(p.q_terminal)
        self.W = np.zeros((n + 1, 4, 4))  # Pi_n' Q Pi_n of J_mpc, n = 1..N
        self.Dv = np.zeros((n + 1, 4, 2))  # d_n = Dv[n] v_des
        for k in range(1, n + 1):
            pi = self.vs.pi(k)
            self.W[k] = pi.T @ (q_term if k == n else q_run) @ pi
            self.Dv[k] = self.vs.offset_map(k)
        # delta p_n = p_{n+1} - p_n for n = 1..N-1 (the sum of J_mpc starts at n = 1)
        self.step_n = np.arange(1, n)
        self.Sd = np.stack([self.sel[k + 1] - self.sel[k] for k in self.step_n]) if n > 1 else (
            np.zeros((0, 2, self.nz)))
        self.R2 = np.diag(p.r_step[:2])
        mh = p.mass_kg * p.com_height_m
        self.soft_scale = np.array([1.0, 1.0, 1.0 / mh, 1.0 / mh])
        # |L_x|/(mH) is the y velocity, |L_y|/(mH) the x velocity
        vx, vy = p.com_vel_limit_mps
        self.soft_lim = np.tile(np.array([p.com_pos_limit_m[0], p.com_pos_limit_m[1], vy, vx]),
                                n + 1)
        self.ns = 4 * (n + 1)
        # constant P blocks from the step cost and the ankle-torque weight
        self.P_steps = 2.0 * np.einsum("kai,ab,kbj->ij", self.Sd, self.R2, self.Sd)
        self.tau_lo = p.t_ss_min_s - p.t_ss_s
        self.tau_hi = p.t_ss_max_s - p.t_ss_s
        # closed-form ALIP exponential pieces (A is two decoupled 2x2 blocks)
        self.omega = np.sqrt(p.gravity_mps2 / p.com_height_m)
        self.mh = mh
        self.A_inv = np.linalg.inv(self.alip.A)
        # -- per-solve shortcuts: everything that does not depend on the inputs -------------
        ep = self.E_const[:, :, 2:]  # footstep columns of x_n (constant)
        self._Ep = ep
        self._WEp = self.W @ ep
        self._P_base = self.P_steps.copy()
        self._P_base[2:, 2:] += 2.0 * np.einsum("nai,naj->ij", ep, self._WEp)
        self._P_base[0, 0] += 2.0 * p.w_time  # (19)
        self._P_base[1, 1] += 2.0 * p.w_ankle
        t = p.t_s2s_s
        alt = np.array([(-1.0) ** k for k in self.step_n])  # sigma_k / sigma_0
        # (18) is linear in v and sigma_0: dp*_k = t v + sigma_0 alt_k l e_y
        self._q_v = -2.0 * t * np.einsum("kai,ab->ib", self.Sd, self.R2)  # (nz, 2)
        self._q_sig = -2.0 * p.step_width_m * np.einsum("k,kai,a->i", alt, self.Sd,
                                                          self.R2[:, 1])
        self._alt_sum = float(alt.sum())
        self._gx = {}
        for s0 in (-1.0, 1.0):
            gx = np.zeros((n, self.nz))
            for k in range(n):
                gx[k] = -self.sigma(s0, k) * (self.sel[k + 1, 1] - self.sel[k, 1])
            self._gx[s0] = gx
        self._hx = np.full(n, -p.crossover_margin_m)
        self._scale_rep = np.tile(self.soft_scale, n + 1)
        self._E_template = self.E_const.copy()
        self._mg = p.mass_kg * p.gravity_mps2
        self._k = mh * self.omega

    # -- (11): exp(A t) in closed form ---------------------------------------------------
    def expm_a(self, t: float) -> np.ndarray:
        """exp(A t) of (1) in closed form (cosh/sinh per plane); equals scipy's expm."""
        ch, sh = np.cosh(self.omega * t), np.sinh(self.omega * t)
        k = self.mh * self.omega
        return np.array(
            [
                [ch, 0.0, 0.0, sh / k],
                [0.0, ch, -sh / k, 0.0],
                [0.0, -k * sh, ch, 0.0],
                [k * sh, 0.0, 0.0, ch],
            ]
        )

    def sigma(self, sigma0: float, n: int) -> float:
        """sigma_n of (18): alternates each step, starting from the current stance's sign."""
        return sigma0 if n % 2 == 0 else -sigma0

    def condense(self, inp: SolveInputs) -> CondensedQp:
        """Build (15) with states eliminated: costs (16)-(19), bounds and crossover rows.

        J_mpc is taken as printed: the running sum starts at n = 1, so x_0 carries no state
        cost and delta p_0 = p_1 - p_0 no step cost (both enter through x_1, x_2). Only the
        columns of T and u depend on the current state (through (12)); the footstep blocks
        are pre-built in __init__.
        """
        p = self.params
        n = self.N
        wt = self.omega * inp.t_nominal
        ch, sh = math.cosh(wt), math.sinh(wt)
        k = self._k
        ad = np.array([[ch, 0.0, 0.0, sh / k], [0.0, ch, -sh / k, 0.0],
                       [0.0, -k * sh, ch, 0.0], [k * sh, 0.0, 0.0, ch]])
        a0 = ad @ inp.x_c  # A_d(T*) x_c                                  (11)
        bc = np.empty((4, 2))
        bc[:, 0] = self.alip.A @ a0  # dA_d/dT x_c = A A_d x_c            (12)/(15b)
        # B_d(T*) = A^-1 (A_d - I) B, in closed form for B = e_4
        bc[:, 1] = ((ch - 1.0) / self._mg, 0.0, 0.0, self.mh * sh / k)
        cmat = self.Phi @ bc  # (N+1, 4, 2): x_n's T and u columns
        e_vec = self.Phi @ a0  # (N+1, 4)
        r = e_vec - self.Dv @ inp.v_des
        wc = self.W @ cmat
        wr = np.einsum("nab,nb->na", self.W, r)
        pmat = self._P_base.copy()
        pmat[:2, :2] += 2.0 * np.einsum("nai,naj->ij", cmat, wc)
        pcp = 2.0 * np.einsum("nai,naj->ij", wc, self._Ep)
        pmat[:2, 2:] = pcp
        pmat[2:, :2] = pcp.T
        qvec = self._q_v @ inp.v_des + inp.sigma0 * self._q_sig
        qvec[:2] += 2.0 * np.einsum("nai,na->i", cmat, wr)
        qvec[2:] += 2.0 * np.einsum("naj,na->j", self._Ep, wr)
        const = float(np.einsum("na,na->", r, wr))
        if n > 1:  # sum over k of dp*_k' R dp*_k with dp*_k = t v + sigma_k l e_y   (18)
            tv = p.t_s2s_s * inp.v_des
            rx, ry = p.r_step[0], p.r_step[1]
            l_ = p.step_width_m
            const += (n - 1) * (rx * tv[0] ** 2 + ry * tv[1] ** 2 + ry * l_**2)
            const += 2.0 * inp.sigma0 * self._alt_sum * ry * l_ * tv[1]
        e_mat = self._E_template.copy()
        e_mat[:, :, :2] = cmat
        cs_mat = e_mat.reshape(self.ns, self.nz) * self._scale_rep[:, None]
        cs_vec = e_vec.reshape(self.ns) * self._scale_rep
        z_lo = np.full(self.nz, -np.inf)
        z_hi = np.full(self.nz, np.inf)
        tau_lo = max(self.tau_lo, -inp.t_nominal)  # T >= 0 as well as the duration bounds
        z_lo[0] = tau_lo
        z_hi[0] = max(self.tau_hi, tau_lo)
        z_lo[1], z_hi[1] = -p.ankle_torque_max_nm, p.ankle_torque_max_nm
        if inp.trust_center is not None:
            z_lo[2:4] = inp.trust_center - inp.trust_radius
            z_hi[2:4] = inp.trust_center + inp.trust_radius
        return CondensedQp(
            pmat, qvec, const, cs_mat, cs_vec, self.soft_lim, p.soft_constraint_cost,
            self._gx[float(inp.sigma0)], self._hx, z_lo, z_hi, e_mat, e_vec,
            crossover_trust_masks,
        )

    def _nominal_step(self, inp: SolveInputs, n: int) -> np.ndarray:
        """delta p_n^* of (18), horizontal part."""
        t = self.params.t_s2s_s
        return np.array([inp.v_des[0] * t,
                         inp.v_des[1] * t + self.sigma(inp.sigma0, n) * self.params.step_width_m])


def build_miqp(model: MpfcModel, inp: SolveInputs, lf: LocalFootholds) -> MiqpData:
    """Assemble (15) with big-M foothold rows (20) and binaries (15e)-(15f), in the stance frame."""
    p = model.params
    n, m = model.N, lf.count
    nx = 4 * (n + 1)
    ip = nx
    iu = ip + 3 * n
    i_t = iu + 1
    i_s = i_t + 1
    nv = i_s + nx
    alip = model.alip
    a_s, b_s = alip.A_s2s, alip.B_s2s
    ad = model.expm_a(inp.t_nominal)
    a0 = ad @ inp.x_c
    b_t = alip.A @ a0
    b_u = model.A_inv @ ((ad - np.eye(4)) @ alip.B)

    def px(k: int) -> slice:
        return slice(ip + 3 * (k - 1), ip + 3 * k)

    # equalities (15b), (15c)
    aeq = np.zeros((nx, nv))
    beq = np.zeros(nx)
    aeq[0:4, 0:4] = np.eye(4)
    aeq[0:4, i_t] = -b_t
    aeq[0:4, iu] = -b_u
    beq[0:4] = a0 - b_t * inp.t_nominal  # x_0 = a0 + b_T (T - T*) + b_u u
    for k in range(n):
        r = slice(4 * (k + 1), 4 * (k + 2))
        aeq[r, 4 * (k + 1): 4 * (k + 2)] = np.eye(4)
        aeq[r, 4 * k: 4 * (k + 1)] = -a_s
        aeq[r, px(k + 1)] = -b_s
        if k >= 1:
            aeq[r, px(k)] = b_s
    # cost (16)-(19) + soft limits
    pm = np.zeros((nv, nv))
    qv = np.zeros(nv)
    const = 0.0
    q_run, q_term = np.diag(p.q_running), np.diag(p.q_terminal)
    for k in range(1, n + 1):
        pi = model.vs.pi(k)
        w = pi.T @ (q_term if k == n else q_run) @ pi
        dk = model.vs.offset_map(k) @ inp.v_des
        sl = slice(4 * k, 4 * (k + 1))
        pm[sl, sl] += 2.0 * w
        qv[sl] -= 2.0 * w @ dk
        const += float(dk @ w @ dk)
    r3 = np.diag(p.r_step)
    t_s2s = p.t_s2s_s
    for k in range(1, n):
        sig = model.sigma(inp.sigma0, k)
        dps = np.array([inp.v_des[0] * t_s2s, inp.v_des[1] * t_s2s + sig * p.step_width_m, 0.0])
        sel = np.zeros((3, nv))
        sel[:, px(k + 1)] = np.eye(3)
        sel[:, px(k)] -= np.eye(3)
        pm += 2.0 * sel.T @ r3 @ sel
        qv -= 2.0 * sel.T @ r3 @ dps
        const += float(dps @ r3 @ dps)
    pm[i_t, i_t] += 2.0 * p.w_time
    qv[i_t] -= 2.0 * p.w_time * inp.t_nominal
    const += p.w_time * inp.t_nominal**2
    pm[iu, iu] += 2.0 * p.w_ankle
    pm[i_s:, i_s:] += 2.0 * p.soft_constraint_cost * np.eye(nx)
    # inequalities: crossover, soft CoM limits, big-M (20)
    rows: list[np.ndarray] = []
    rows_mu: list[np.ndarray] = []
    rhs: list[float] = []

    def add(row: np.ndarray, rhs_v: float, mu_row: np.ndarray | None = None) -> None:
        rows.append(row)
        rows_mu.append(np.zeros(n * m) if mu_row is None else mu_row)
        rhs.append(rhs_v)

    for k in range(n):
        sig = model.sigma(inp.sigma0, k)
        row = np.zeros(nv)
        row[px(k + 1).start + 1] = -sig
        if k >= 1:
            row[px(k).start + 1] = sig
        add(row, -p.crossover_margin_m)
    for j in range(nx):
        for sgn in (1.0, -1.0):
            row = np.zeros(nv)
            row[j] = sgn * model.soft_scale[j % 4]
            row[i_s + j] = -1.0
            add(row, float(model.soft_lim[j]))
    big_m = p.big_m_m
    a3, b3, n3, d3 = lf.three_d()
    for k in range(1, n + 1):
        for i in range(m):
            mu_row = np.zeros(n * m)
            mu_row[(k - 1) * m + i] = big_m
            real = np.isfinite(b3[i])
            for a_row, b_val in zip(a3[i][real], b3[i][real], strict=True):
                row = np.zeros(nv)
                row[px(k)] = a_row
                add(row, float(b_val) + big_m, mu_row)  # (20a)
            for sgn in (1.0, -1.0):
                row = np.zeros(nv)
                row[px(k)] = sgn * n3[i]
                add(row, sgn * float(d3[i]) + big_m, mu_row)  # (20b), (20c)
    smu = np.zeros((n, n * m))
    for k in range(n):
        smu[k, k * m: (k + 1) * m] = 1.0  # (15e)
    lb = np.full(nv, -np.inf)
    ub = np.full(nv, np.inf)
    tau_lo = max(model.tau_lo, -inp.t_nominal)
    lb[i_t] = inp.t_nominal + tau_lo
    ub[i_t] = inp.t_nominal + max(model.tau_hi, tau_lo)
    lb[iu], ub[iu] = -p.ankle_torque_max_nm, p.ankle_torque_max_nm
    if inp.trust_center is not None:
        lb[ip: ip + 2] = inp.trust_center - inp.trust_radius
        ub[ip: ip + 2] = inp.trust_center + inp.trust_radius
    lb[i_s:] = 0.0
    return MiqpData(
        pm, qv, const, aeq, beq, np.array(rows), np.array(rows_mu), np.array(rhs), smu, lb, ub,
        n, m, ip, iu, i_t, inp.t_nominal,
    )
