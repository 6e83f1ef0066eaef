"""The compiled (numba) paths of the OSC against straightforward references built from
MuJoCo's own functions and dense numpy algebra: a dropped or wrong term fails these."""

from __future__ import annotations

import math

import mujoco
import numpy as np

from processes.osc.model import CassieModel
from tools.benchmarks.osc import kkt_residual, tight_optimum


def _states(q_stand: np.ndarray, n: int = 4) -> list[tuple[np.ndarray, np.ndarray]]:
    """Standing pose, and poses moved off it (base, joints) with random velocities: rods
    and springs off their closures too, so no term vanishes by accident."""
    rng = np.random.default_rng(11)
    out = [(q_stand.copy(), np.zeros(32))]
    for _ in range(n):
        q = q_stand.copy()
        q[0:3] += rng.normal(scale=0.05, size=3)
        quat = q[3:7] + rng.normal(scale=0.1, size=4)
        q[3:7] = quat / np.linalg.norm(quat)
        q[7:] += rng.normal(scale=0.05, size=len(q) - 7)
        out.append((q, rng.normal(scale=1.0, size=32)))
    return out


def _reference_model(cm: CassieModel, q: np.ndarray, v: np.ndarray) -> dict[str, np.ndarray]:
    """Every term of CassieModel.update from mj_jac / mj_jacDot / mj_jacSubtreeCom and numpy."""
    m, d = cm.m, cm.d
    d.qpos[:] = q
    d.qvel[:] = v
    mujoco.mj_fwdPosition(m, d)
    mujoco.mj_fwdVelocity(m, d)
    d.qacc[:] = 0.0
    mujoco.mj_rnePostConstraint(m, d)
    nv, ne = m.nv, len(cm.eq_b1)
    pts, J, Jdv = [], [], []
    for b, loc in zip(cm._pt_body, cm._pt_local, strict=True):
        p = d.xmat[b].reshape(3, 3) @ loc + d.xpos[b]
        pts.append(p)
    pts = np.array(pts)
    pts[2 * ne :, 2] -= 0.02
    for b, p in zip(cm._pt_body, pts, strict=True):
        jp, jd = np.zeros((3, nv)), np.zeros((3, nv))
        mujoco.mj_jac(m, d, jp, None, p, int(b))
        mujoco.mj_jacDot(m, d, jd, None, p, int(b))
        J.append(jp)
        Jdv.append(jd @ v)
    J, Jdv = np.array(J), np.array(Jdv)
    Jr, ar = J[:ne] - J[ne : 2 * ne], Jdv[:ne] - Jdv[ne : 2 * ne]
    Jh, jhv = np.zeros((14, nv)), np.zeros(14)
    for j, k in enumerate(cm._planar_k):
        E = d.xmat[cm.eq_b2[k]].reshape(3, 3).T[0:2]
        w = d.cvel[cm.eq_b2[k], 0:3]
        Jh[2 * j : 2 * j + 2] = E @ Jr[k]
        jhv[2 * j : 2 * j + 2] = E @ (ar[k] - np.cross(w, Jr[k] @ v))
    for j, k in enumerate(cm._achilles_k):
        Jh[4 + 3 * j : 7 + 3 * j] = Jr[k]
        jhv[4 + 3 * j : 7 + 3 * j] = ar[k]
    for k, dof in enumerate(cm.spring_dof):
        Jh[10 + k, dof] = 1.0
    Jcom = np.zeros((3, nv))
    mujoco.mj_jacSubtreeCom(m, d, Jcom, cm.pelvis_body)
    Jc = J[2 * ne :].reshape(12, nv)
    cdv = d.cfrc_int[cm.pelvis_body, 3:6] / cm.mass - np.array([0.0, 0.0, 9.81])
    return {"h": d.qfrc_bias - d.qfrc_passive, "Jh": Jh, "Jh_dot_v": jhv, "Jc": Jc,
            "Jc_dot_v": Jdv[2 * ne :].reshape(12), "p_contact": pts[2 * ne :],
            "v_contact": (Jc @ v).reshape(4, 3), "J_com": Jcom,
            "com": d.subtree_com[cm.pelvis_body].copy(), "com_vel": Jcom @ v, "com_dot_v": cdv,
            "R_pelvis": d.xmat[cm.pelvis_body].reshape(3, 3).copy(),
            "foot_axis": d.xaxis[cm.foot_joint_axis_jnt].copy(),
            "rod_residual": pts[:ne] - pts[ne : 2 * ne]}


def test_compiled_kinematics_match_mujoco_jacobians(sim_model, q_stand):
    cm, ref = CassieModel(sim_model), CassieModel(sim_model)
    for q, v in _states(q_stand):
        cm.update(q, v)
        want = _reference_model(ref, q, v)
        for name, a in want.items():
            got = getattr(cm, name)
            scale = max(1.0, float(np.abs(a).max()))
            assert np.abs(got - a).max() <= 1e-12 * scale, name
        # the float lists the tasks read are the arrays' values
        assert cm.com_l == cm.com.tolist() and cm.p_contact_l == cm.p_contact.tolist()


def _reference_qp(cm: CassieModel, qp, tasks, stance: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray]:
    """(P, c) of (14) condensed by dense algebra: the KKT system of (14b)-(14c) solved for the
    affine map x -> dv, then the Hessian and gradient of the cost (14a) written term by term:
    1/2 sum w (J dv - b)^2 over ||dv||^2, task and soft-contact rows, 1/2 w_u ||u||^2,
    1/2 w_f ||lam||^2, the change penalties and the contact-moment cost."""
    nv, nu, nh = cm.nv, cm.nu, cm.n_holonomic
    wt = qp.wts
    rows = np.flatnonzero(np.repeat(stance, 3))
    n = nu + len(rows)
    M = np.zeros((nv, nv))
    mujoco.mj_fullM(cm.m, cm.d, M)
    K = np.block([[M, -cm.Jh.T], [cm.Jh, np.zeros((nh, nh))]])
    F = np.hstack([cm.B, cm.Jc[rows].T])  # generalized forces of x
    rhs = np.zeros((nv + nh, n + 1))
    rhs[:nv, :n] = F
    rhs[:nv, n] = -cm.h
    rhs[nv:, n] = -cm.Jh_dot_v
    sol = np.linalg.solve(K, rhs)
    Gd, gd = sol[:nv, :n], sol[:nv, n]  # dv = Gd x + gd
    J = [np.eye(nv), tasks.matrix(cm), cm.Jc[rows]]
    b = [np.zeros(nv), tasks.b[: tasks.n], -cm.Jc_dot_v[rows]]
    w = [np.full(nv, wt.accel), tasks.w[: tasks.n], np.full(len(rows), wt.contact_slack)]
    P, c = np.zeros((n, n)), np.zeros(n)
    for Jr, br, wr in zip(J, b, w, strict=True):
        A = Jr @ Gd
        r = Jr @ gd - br
        P += A.T @ (wr[:, None] * A)
        c += A.T @ (wr * r)
    reg = np.r_[np.full(nu, wt.torque + wt.torque_change),
                np.full(len(rows), wt.force + wt.force_change)]
    P += np.diag(reg)
    c[:nu] -= wt.torque_change * qp.u_prev
    c[nu:] -= wt.force_change * qp.lam_prev[rows]
    k = qp.moment_count
    if k:
        A = qp.moment_rows[:k, rows]
        P[nu:, nu:] += qp.moment_weight * A.T @ A
        c[nu:] -= qp.moment_weight * A.T @ qp.moment_target[:k]
    return P, c


def _tasks_of_every_kind(qp, cm: CassieModel, rng: np.random.Generator) -> None:
    from processes.osc.qp import ROW_COM, ROW_CONTACT, ROW_DOF

    rows = qp.rows
    rows.reset()
    rows.add_row(ROW_COM + 2, 1.0, 0.3, 2.0)
    rows.add_row(ROW_CONTACT + 7, 0.5, -1.0, 3.0, ROW_CONTACT + 10, 1.0)  # a midpoint
    rows.add_row(ROW_CONTACT + 2, 7.0, 0.2, 1.5, ROW_CONTACT + 5, -1.0)  # a pitch row
    rows.add_row(ROW_DOF + 4, 1.0, -0.7, 0.8)
    rows.add(rng.normal(size=(2, cm.nv)), rng.normal(size=2), rng.normal(size=2), 0.5)


def test_compiled_condensation_matches_dense_reference(sim_model, q_stand):
    """Every weight ~1 so that no term of (14a) is negligible: a dropped term fails this."""
    from processes.osc.qp import OscQP, QpWeights

    w = QpWeights(contact_slack=3.0, torque=0.7, force=0.4, accel=0.9, torque_change=0.6,
                  force_change=0.5)
    cm = CassieModel(sim_model)
    qp = OscQP(cm, w)
    rng = np.random.default_rng(5)
    for i, (q, v) in enumerate(_states(q_stand, 3)):
        cm.update(q, v)
        _tasks_of_every_kind(qp, cm, rng)
        qp.u_prev[:] = rng.normal(size=cm.nu)
        qp.lam_prev[:] = rng.normal(size=12)
        qp.moment_count = i % 3
        qp.moment_rows[:] = rng.normal(size=qp.moment_rows.shape)
        qp.moment_target[:] = rng.normal(size=2)
        qp.moment_weight = 1.3
        for stance in (np.ones(4, dtype=bool), np.array([True, True, False, False])):
            P, c = qp._build(qp.rows, qp._rows_of(stance)[0])
            P_ref, c_ref = _reference_qp(cm, qp, qp.rows, stance)
            assert np.abs(P - P_ref).max() <= 1e-9 * np.abs(P_ref).max()
            assert np.abs(c - c_ref).max() <= 1e-9 * np.abs(c_ref).max()
            assert np.array_equal(P, P.T)


def test_osc_qp_solution_is_the_optimum_of_its_qp_with_limits_active(q_stand):
    """On the controller's own QPs (CoM demands that saturate motors, a walking double
    stance whose trailing-foot force cap binds) the compiled active-set solution satisfies
    the KKT conditions (checked independently here) and costs no more than a tightly
    converged piqp's answer, so it is the QP's optimum."""
    from processes.osc.controller import OscController
    from processes.osc.tasks import DEFAULT_GAINS_FILE, OscGains, OscParams
    from processes.osc.walking import DOUBLE_AFTER_LEFT
    from runtime.params import load

    from .test_qp import _Cmd, _Plan

    params = OscParams.from_gains(load(OscGains, DEFAULT_GAINS_FILE))
    params.standing.com.kp[:] = 3e3
    params.standing.com.refresh()
    params.standing.com_offset_x = 0.05
    params.standing.xy_ramp_s = 0.0
    osc = OscController(params)
    rng = np.random.default_rng(2)
    n_active = compared = 0
    for k in range(12):
        v = rng.normal(scale=0.5, size=32)
        if k < 8:  # standing, CoM pushed hard
            _, dbg = osc.update(0.0005 * k, q_stand, v)
        else:  # walking double stance: the trailing foot's force cap binds
            cm = osc.model
            plan = _Plan(DOUBLE_AFTER_LEFT + 1, 0.0, 0.02, cm.p_contact[2:4].mean(axis=0),
                         cm.p_contact[0:2].mean(axis=0))
            plan.stance = 1
            _, dbg = osc.update(0.01 + 0.004 * (k - 8), q_stand, v, plan, _Cmd())
        assert dbg.qp_status == 1 and dbg.qp_iterations == 0, dbg.status  # no piqp needed
        P, c, lo, hi, G = osc.qp.last_problem()
        x = np.concatenate([osc.qp.u, osc.qp.lam[np.repeat(osc.stance, 3)]])
        viol, stat, na = kkt_residual(P, c, lo, hi, G, x)
        assert viol <= 1e-9 and stat <= 1e-12, (viol, stat)
        n_active += na
        ref = tight_optimum(P, c, lo, hi, G)  # (it fails on a zero force cap: lo = hi = 0)
        if ref is not None:
            compared += 1
            cost = 0.5 * x @ P @ x + c @ x
            assert cost <= 0.5 * ref @ P @ ref + c @ ref + 1e-12 * abs(cost)
    assert n_active >= 12  # constraints were active: not just the unconstrained minimiser
    assert compared >= 8


def _basis3(tau: float, nc: int) -> np.ndarray:
    pw = tau ** np.arange(nc)
    i = np.arange(nc)
    d1 = np.r_[0.0, i[1:] * pw[:-1]]
    d2 = np.r_[0.0, 0.0, i[2:] * (i[2:] - 1) * pw[:-2]]
    return np.array([pw, d1, d2])


def test_compiled_swing_solve_matches_dense_kkt_of_23():
    """Each re-solve of the swing QP (23) against the KKT system written out with numpy:
    end conditions, waypoint rows (the step-up set too) and the continuity rows."""
    from processes.osc.walking import SwingFootTrajectory, swing_waypoints

    rng = np.random.default_rng(4)
    for step_up in (0.0, 0.05):
        traj = SwingFootTrajectory(8, step_up_min=step_up)
        nc = traj.nc
        p0 = np.array([0.0, -0.1, 0.0])
        traj.start(0.0, 0.0, 0.3, p0)
        t = 0.0
        for _ in range(40):
            t += 0.004
            td = 0.3 + rng.normal(scale=0.01)
            des = np.array([0.3, -0.1, 0.15]) + rng.normal(scale=0.02, size=3)
            coef0, T0, tp = traj.coef.copy(), traj.T, traj.t_prev
            traj.update(t, td, des, 0.15)
            T_new = max(td - traj.liftoff, 0.05)
            if T_new - (tp - traj.liftoff) <= traj.freeze_s:
                continue
            tau_prev = min(max(tp / T0, 0.0), 1.0)
            tau_k = tp / T_new
            prev = _basis3(tau_prev, nc) @ coef0
            s = T_new / T0
            wps = [w for w in swing_waypoints(p0, des, 0.15, step_up, traj.step_up_clearance,
                                              traj.step_up_height, traj.lift_tau,
                                              traj.approach_tau)
                   if tau_k < w[0] - traj.mid_margin]
            A = np.vstack([_basis3(1.0, nc)] + [_basis3(w[0], nc)[:1] for w in wps]
                          + [_basis3(tau_k, nc)])
            d = np.vstack([des, np.zeros((2, 3))] + [np.array(w[1])[None] for w in wps]
                          + [prev[0], prev[1] * s, prev[2] * s * s])
            K = np.block([[traj._Q2, A.T], [A, np.zeros((len(A), len(A)))]])
            want = np.linalg.solve(K, np.vstack([np.zeros((nc, 3)), d]))[:nc]
            # cond(K) ~ 1e8: two LU solves agree to ~1e-9 relative, the exact one to ~1e-9
            np.testing.assert_allclose(traj.coef, want, rtol=1e-7, atol=1e-7)
            assert T_new == traj.T
            pos, vel, acc = traj.evaluate(t)
            B = _basis3(min(max((t - traj.liftoff) / traj.T, 0.0), 1.0), nc) @ traj.coef
            np.testing.assert_allclose(pos, B[0], atol=1e-12)
            np.testing.assert_allclose(vel, B[1] / traj.T, atol=1e-10)
            np.testing.assert_allclose(acc, B[2] / traj.T**2, atol=1e-8)


def _capture(monkeypatch, module, name: str) -> list:
    """Record the arguments of every call of a module's compiled kernel (still calling it)."""
    calls: list = []
    kernel = getattr(module, name)

    def spy(*args):
        calls.append([a.copy() if isinstance(a, np.ndarray) else a for a in args])
        return kernel(*args)

    monkeypatch.setattr(module, name, spy)
    return calls


def _rows_equal(rows, ref, log_errors: list[float], ref_log) -> None:
    n = ref.n
    assert rows.n == n
    np.testing.assert_array_equal(rows.ri[:n], ref.ri[:n])
    np.testing.assert_allclose(rows.rf[:n], ref.rf[:n], rtol=1e-13, atol=1e-13)
    np.testing.assert_allclose(log_errors, ref_log.errors, rtol=1e-12, atol=1e-15)


def test_compiled_task_rows_match_the_python_reference_tasks(q_stand, monkeypatch):
    """Standing, single and double stance ticks at moving states: the compiled walking and
    standing rows (J sources, coefficients, b, w), task errors and contact-moment rows are
    those of the straightforward Python tasks (tests/osc/reference_tasks.py) on the same
    references."""
    from processes.osc import standing, walking
    from processes.osc.controller import OscController
    from processes.osc.qp import TaskRows
    from processes.osc.walking import DOUBLE_AFTER_LEFT, SINGLE_LEFT

    from . import reference_tasks as ref
    from .test_qp import _Cmd, _Plan

    st_calls = _capture(monkeypatch, standing, "standing_rows")
    wk_calls = _capture(monkeypatch, walking, "walking_rows")
    osc = OscController()
    m, p = osc.model, osc.params
    rng = np.random.default_rng(9)
    checked = {"standing": 0, "single": 0, "double": 0}
    for k in range(9):
        v = rng.normal(scale=0.4, size=32)
        q = q_stand.copy()
        q[7:] += rng.normal(scale=0.02, size=len(q) - 7)
        cm = m
        if k < 3:
            osc.update(0.001 * k, q, v)
        else:
            st = cm.p_contact[0:2].mean(axis=0)
            nxt = cm.p_contact[2:4].mean(axis=0) + np.array([0.12, 0.0, 0.03])
            if k < 6:  # weight transfer onto the left foot, CoP rows
                plan = _Plan(DOUBLE_AFTER_LEFT, 0.0, 0.05, st, nxt)
                plan.ankle_torque = 0.0
            else:
                plan = _Plan(SINGLE_LEFT, 0.01, 0.31, st, nxt)
            cmd = _Cmd()
            cmd.yaw_rate = 0.3  # turning: the pelvis rows' yaw-rate term is not zero
            osc.update(0.002 * k, q, v, plan, cmd)
        rows, log = osc.rows, osc.log
        want, want_log = TaskRows(cm.nv), ref.TaskLog()
        if k < 3:
            a = st_calls[-1]
            x, y, z, yaw, hip_des = a[10], a[11], a[12], a[13], a[16]
            ref.add_com_task(want, want_log, cm, p.standing.com, [x, y, z], [0.0] * 3,
                             [0.0] * 3)
            ref.PelvisOrientationTask(cm.nv).add(want, want_log, cm, v, p.standing.pelvis, yaw,
                                                 0.0)
            for side in range(2):
                ref.add_joint_task(want, want_log, cm, q, v, int(cm.hip_yaw_qpos[side]),
                                   int(cm.hip_yaw_dof[side]), p.standing.hip_yaw,
                                   float(hip_des[side]), "hip_yaw")
            _rows_equal(rows, want, log.errors, want_log)
            checked["standing"] += 1
            continue
        assert osc.mode == 0, osc.debug.status
        a = wk_calls[-1]
        moment_rows = a[8]  # as the kernel received them; it wrote osc.qp.moment_rows
        z, zd, yaw_rate, yaw, single, stance = a[14], a[15], a[16], a[17], a[18], a[19]
        swing_ref, toe, hip_q, hip_d, ankle, cop_f = a[20], a[21], a[22], a[23], a[24], a[25]
        w = p.walking
        c, cv = cm.com_l, cm.com_vel_l
        ref.add_com_task(want, want_log, cm, w.com, [c[0], c[1], z], [cv[0], cv[1], zd],
                         [0.0] * 3)
        ref.PelvisOrientationTask(cm.nv).add(want, want_log, cm, v, w.pelvis, cm.pelvis_yaw(),
                                             yaw_rate)
        want_moment = moment_rows.copy()
        sw = 1 - stance
        if single:
            ref.add_foot_position_task(want, want_log, cm, sw, w.swing_foot,
                                       *swing_ref.tolist())
            ref.add_foot_pitch_task(want, want_log, cm, sw, w.toe, toe)
            ref.add_joint_task(want, want_log, cm, q, v, hip_q, hip_d, w.hip_yaw, 0.0, "hip")
            assert ankle
            centre = cm.foot_center(stance).tolist()
            ref.moment_row(want_moment[0], cm.p_contact_l, (2 * stance, 2 * stance + 1),
                           centre, (-math.sin(yaw), math.cos(yaw), 0.0))
            checked["single"] += 1
        else:
            assert cop_f >= 0.0
            pm, pp = cm.foot_center(sw), cm.foot_center(stance)
            cop = (pm + cop_f * (pp - pm)).tolist()
            cy, sy = math.cos(yaw), math.sin(yaw)
            ref.moment_row(want_moment[0], cm.p_contact_l, range(4), cop, (cy, sy, 0.0))
            ref.moment_row(want_moment[1], cm.p_contact_l, range(4), cop, (-sy, cy, 0.0))
            checked["double"] += 1
        _rows_equal(rows, want, log.errors, want_log)
        np.testing.assert_allclose(osc.qp.moment_rows, want_moment, rtol=1e-14, atol=1e-15)
    assert checked == {"standing": 3, "single": 3, "double": 3}


def test_no_kernel_compiles_on_a_tick(q_stand):
    """Every compiled kernel is compiled (or loaded from numba's cache) when the controller
    is built: a tick that met a new argument type would stall for seconds to compile."""
    import numba

    from processes.osc import activeset, controller, model, qp, safety, standing, tasks, walking
    from processes.osc.walking import DOUBLE_AFTER_LEFT, SINGLE_LEFT

    from .test_qp import _Cmd, _Plan

    def signatures() -> dict[str, int]:
        out = {}
        for mod in (activeset, model, qp, safety, standing, tasks, walking):
            for name, obj in vars(mod).items():
                if isinstance(obj, numba.core.registry.CPUDispatcher):
                    out[f"{mod.__name__}.{name}"] = len(obj.signatures)
        return out

    osc = controller.OscController()
    before = signatures()
    cm = osc.model
    osc.update(0.0, q_stand, np.zeros(32))
    st, nxt = cm.p_contact[0:2].mean(axis=0), cm.p_contact[2:4].mean(axis=0)
    osc.update(0.005, q_stand, np.zeros(32), _Plan(DOUBLE_AFTER_LEFT, 0.0, 0.3, st, nxt), _Cmd())
    osc.update(0.01, q_stand, np.zeros(32), _Plan(SINGLE_LEFT, 0.0, 0.3, st, nxt), _Cmd())
    assert osc.mode == 0
    # states the kernels never see directly: strided views, another float type
    q_strided = np.repeat(q_stand, 2)[::2]
    osc.update(0.0105, q_strided, np.zeros(64)[::2], _Plan(SINGLE_LEFT, 0.0, 0.3, st, nxt),
               _Cmd())
    osc.update(0.011, q_stand.astype(np.float32), np.zeros(32, np.float32),
               _Plan(SINGLE_LEFT, 0.0, 0.3, st, nxt), _Cmd())
    assert osc.mode == 0
    assert signatures() == before
