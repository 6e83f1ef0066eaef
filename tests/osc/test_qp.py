"""The condensed QP (14): its solution satisfies the equations it was built from."""

from __future__ import annotations

import mujoco
import numpy as np

from processes.osc.controller import OscController
from processes.osc.tasks import DEFAULT_GAINS_FILE, OscGains, OscParams
from processes.osc.walking import DOUBLE_AFTER_LEFT, SINGLE_LEFT
from runtime.params import load


class _Plan:
    """Minimal mpfc_output_t stand-in (no header: always fresh)."""

    def __init__(self, gait_state: int, t_lo: float, t_td: float, stance_xyz, next_xyz) -> None:
        self.gait_state = gait_state
        self.stance = 0
        self.stance_foot_world = list(stance_xyz)
        self.next_footstep_world = list(next_xyz)
        self.stance_yaw = 0.0
        self.prev_switch_time_s = t_lo
        self.next_switch_time_s = t_td
        self.ankle_torque = 5.0
        self.solve_status = 0


class _Cmd:
    mode = 0
    yaw_rate = 0.0
    vx = vy = 0.0


def _check_solution(osc: OscController, stance: np.ndarray) -> None:
    cm, qp = osc.model, osc.qp
    qp.recover()
    M = np.zeros((cm.nv, cm.nv))
    mujoco.mj_fullM(cm.m, cm.d, M)
    # (14b): M dv + h = B u + Jh^T lambda_h + Jc^T lambda_c
    lhs = M @ qp.dv + cm.h
    rhs = cm.B @ qp.u + cm.Jh.T @ qp.lam_h + cm.Jc.T @ qp.lam
    assert np.abs(lhs - rhs).max() < 1e-8 * max(1.0, np.abs(lhs).max())
    # (14c): Jh dv = -Jh_dot v
    assert np.abs(cm.Jh @ qp.dv + cm.Jh_dot_v).max() < 1e-8
    lam = qp.lam.reshape(4, 3)
    mu = osc.params.qp.mu
    for i in range(4):
        if stance[i]:
            # (14e): linearised friction pyramid, unilateral normal force
            assert lam[i, 2] >= -1e-6
            assert abs(lam[i, 0]) <= mu * lam[i, 2] + 1e-5
            assert abs(lam[i, 1]) <= mu * lam[i, 2] + 1e-5
        else:
            assert np.all(lam[i] == 0.0)  # swing points carry no force
    # (14f): torque limits
    assert np.all(np.abs(qp.u) <= cm.u_max + 1e-6)


def test_standing_qp_solution_satisfies_dynamics_holonomic_and_friction(q_stand):
    osc = OscController()
    rng = np.random.default_rng(3)
    for _ in range(5):
        v = rng.normal(size=32) * 0.3
        q = q_stand.copy()
        q[0:3] += rng.normal(size=3) * 0.01
        _, dbg = osc.update(0.0, q, v)
        assert dbg.qp_status == 1, dbg.status
        _check_solution(osc, osc.stance)
    # at rest the feet carry the weight: total normal force close to m g
    osc = OscController()
    _, dbg = osc.update(0.0, q_stand, np.zeros(32))
    fz = osc.qp.lam.reshape(4, 3)[:, 2].sum()
    assert abs(fz - osc.model.mass * 9.81) < 0.1 * osc.model.mass * 9.81


def test_single_stance_qp_puts_no_force_on_the_swing_foot(q_stand):
    osc = OscController()
    osc.update(0.0, q_stand, np.zeros(32))  # standing first (start-up)
    cm = osc.model
    st = cm.p_contact[0:2].mean(axis=0)
    nxt = cm.p_contact[2:4].mean(axis=0) + np.array([0.1, 0, 0])
    osc.update(0.005, q_stand, np.zeros(32), _Plan(DOUBLE_AFTER_LEFT, 0.0, 0.3, st, nxt), _Cmd())
    plan = _Plan(SINGLE_LEFT, 0.0, 0.3, st, nxt)
    _, dbg = osc.update(0.01, q_stand, np.zeros(32), plan, _Cmd())
    assert dbg.mode == 0 and dbg.qp_status == 1, dbg.status
    assert list(osc.stance) == [True, True, False, False]
    _check_solution(osc, osc.stance)
    assert "swing_foot" in dbg.task_names


def test_double_stance_plan_uses_all_four_contact_points(q_stand):
    osc = OscController()
    osc.update(0.0, q_stand, np.zeros(32))
    cm = osc.model
    plan = _Plan(DOUBLE_AFTER_LEFT, 0.0, 0.4, cm.p_contact[0:2].mean(axis=0),
                 cm.p_contact[2:4].mean(axis=0))
    _, dbg = osc.update(0.01, q_stand, np.zeros(32), plan, _Cmd())
    assert dbg.mode == 0 and dbg.qp_status == 1
    assert osc.stance.all()
    _check_solution(osc, osc.stance)


def test_torques_stay_within_limits_for_huge_tracking_errors(q_stand):
    params = OscParams.from_gains(load(OscGains, DEFAULT_GAINS_FILE))
    params.standing.com.kp[:] = 1e5  # demand an impossible CoM acceleration
    params.standing.com.refresh()
    params.standing.com_offset_x = 0.1
    params.standing.xy_ramp_s = 0.0  # the whole offset at once
    osc = OscController(params)
    v = np.zeros(32)
    v[3:6] = (5.0, -5.0, 3.0)
    peak = np.zeros(10)
    for k in range(100):  # the torque-change penalty lets torques grow over a few ticks
        u, dbg = osc.update(0.0005 * k, q_stand, v)
        assert dbg.qp_status == 1
        assert np.all(np.isfinite(u))
        assert np.all(np.abs(u) <= osc.model.u_max + 1e-9)
        peak = np.maximum(peak, np.abs(u))
    # such an error saturates at least one motor: the limits are active, not just far away
    assert np.any(peak > 0.99 * osc.model.u_max)


def test_mpfc_ankle_torque_becomes_the_ground_moment_about_the_stance_foot(q_stand):
    """Section V-D with the ALIP sign: u is the ground's moment on the robot about the stance
    contact point (the blade midpoint the ALIP state is measured from), stance-frame y axis."""
    params = OscParams.from_gains(load(OscGains, DEFAULT_GAINS_FILE))
    params.walking.ankle_torque_weight = 1e4  # make the cost dominate for the check
    osc = OscController(params)
    osc.update(0.0, q_stand, np.zeros(32))
    cm = osc.model
    st = cm.p_contact[0:2].mean(axis=0)
    ds = _Plan(DOUBLE_AFTER_LEFT, 0.0, 0.3, st, cm.p_contact[2:4].mean(axis=0))
    osc.update(0.005, q_stand, np.zeros(32), ds, _Cmd())  # hand over in double stance
    for u_alip in (8.0, -8.0, 0.0):
        plan = _Plan(SINGLE_LEFT, 0.0, 0.3, st, cm.p_contact[2:4].mean(axis=0))
        plan.ankle_torque = u_alip
        for k in range(40):  # let the torque-change penalty settle
            _, dbg = osc.update(0.01 + 0.0005 * k, q_stand, np.zeros(32), plan, _Cmd())
        assert dbg.qp_status == 1
        lam = osc.qp.lam.reshape(4, 3)
        about = cm.foot_center(0)
        moment = sum(np.cross(cm.p_contact[i] - about, lam[i]) for i in (0, 1))[1]
        assert abs(moment - u_alip) < 1.0, (u_alip, moment)


def test_double_stance_unloads_the_trailing_foot_linearly(q_stand):
    """(2)/(7): over double stance the trailing foot carries at most (1 - f) m g, and none at
    liftoff, so it leaves the ground unloaded."""
    osc = OscController()
    osc.update(0.0, q_stand, np.zeros(32))
    cm = osc.model
    weight = cm.mass * 9.81
    # right foot just landed (stance 1, gait state 3): the left foot trails
    plan = _Plan(DOUBLE_AFTER_LEFT + 1, 0.0, 0.1, cm.p_contact[2:4].mean(axis=0),
                 cm.p_contact[0:2].mean(axis=0))
    plan.stance = 1
    plan.ankle_torque = 0.0
    loads = []
    for k in range(0, 201):
        t = 0.0005 * k
        _, dbg = osc.update(t, q_stand, np.zeros(32), plan, _Cmd())
        assert dbg.qp_status == 1
        trail = float(osc.qp.lam.reshape(4, 3)[0:2, 2].sum())
        assert trail <= (1.0 - min(t / 0.1, 1.0)) * weight + 1e-6
        loads.append(trail)
    assert loads[-1] < 1e-6  # fully unloaded at the end of double stance


def test_walking_out_of_standing_keeps_the_leading_foot_loaded_then_unloads_it_slowly(q_stand):
    """Handed over from standing into the MPFC's weight shift (a double stance longer than
    ``start_unload_s``), the leading foot carries at least its standing share (m g / 4 a
    point) falling to ``start_fz_min`` over ``start_unload_s`` (at the paper's CoP target, the
    trailing foot, it lost 85 N a point in a tick and lifted); a walk begun at the second tick
    (the springs not loaded yet) or into a double stance of T_ds has no such floor."""
    osc = OscController()
    p = osc.params.walking
    for k in range(60):  # stand first, 30 ms (``STOOD_LOADED_S``: the springs loaded)
        osc.update(0.0005 * k, q_stand, np.zeros(32))
    cm = osc.model
    share = 0.25 * cm.mass * 9.81
    t0 = 0.03
    plan = _Plan(DOUBLE_AFTER_LEFT, t0, t0 + 0.5, cm.p_contact[0:2].mean(axis=0),
                 cm.p_contact[2:4].mean(axis=0))
    plan.ankle_torque = 0.0
    for k in range(0, 401, 4):
        t = t0 + 0.0005 * k
        _, dbg = osc.update(t, q_stand, np.zeros(32), plan, _Cmd())
        assert dbg.qp_status == 1 and osc.mode == 0
        lead = osc.qp.lam.reshape(4, 3)[0:2, 2]
        floor = max(p.start_fz_min, share * (1.0 - (t - t0) / p.start_unload_s))
        assert np.all(lead >= floor - 1e-6), (t, lead, floor)
    ss = _Plan(SINGLE_LEFT, t0 + 0.5, t0 + 0.8, plan.stance_foot_world, plan.next_footstep_world)
    osc.update(t0 + 0.5, q_stand, np.zeros(32), ss, _Cmd())
    assert osc.walking.fz_floor is None and not osc.walking.from_standing

    first = OscController()  # walks at its second tick (the harness's start): no floor
    first.update(0.0, q_stand, np.zeros(32))
    first.update(0.0005, q_stand, np.zeros(32), plan, _Cmd())
    assert first.mode == 0 and first.walking.fz_floor is None

    short = OscController()  # out of standing into a double stance of T_ds: no time for it
    for k in range(60):
        short.update(0.0005 * k, q_stand, np.zeros(32))
    plan.prev_switch_time_s, plan.next_switch_time_s = t0, t0 + 0.1
    short.update(t0, q_stand, np.zeros(32), plan, _Cmd())
    assert short.mode == 0 and short.walking.fz_floor is None


def test_closed_form_optimum_matches_piqp_when_it_certifies_one():
    """The compiled active-set solve returns piqp's optimum (tightly converged), or None."""
    from processes.osc.qp import _Solver

    rng = np.random.default_rng(7)
    u_max = np.array([112.5, 112.5, 195.2, 195.2, 45.0] * 2)
    certified = 0
    for trial in range(60):
        nc = (2, 4)[trial % 2]
        n = 10 + 3 * nc
        closed = _Solver(n, nc, u_max, 0.6, 1500.0, 15.0 * (trial % 3 == 0))
        ref = _Solver(n, nc, u_max, 0.6, 1500.0, 15.0 * (trial % 3 == 0))
        st = ref.solver.settings  # a tightly converged reference
        st.eps_abs = st.eps_rel = st.eps_duality_gap_abs = st.eps_duality_gap_rel = 1e-10
        st.max_iter = 200
        L = rng.normal(size=(n, n))
        P = L @ L.T + 0.1 * np.eye(n)
        x_target = np.concatenate([rng.normal(scale=60.0, size=10),
                                   np.tile([rng.normal(scale=40), rng.normal(scale=40),
                                            abs(rng.normal(scale=100))], nc)])
        c = -P @ x_target
        x = closed.closed_form(P, c)
        status, _, x_ref = ref.solve(np.asfortranarray(P), c)
        assert status == 1
        if x is not None:
            certified += 1
            np.testing.assert_allclose(x, x_ref, atol=1e-3 * (1.0 + np.abs(x_ref).max()))
    assert certified == 60  # the exact active-set method certifies every one of them
