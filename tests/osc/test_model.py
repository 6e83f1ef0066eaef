"""The controller model: 14 independent holonomic rows and exact Jdot v terms."""

from __future__ import annotations

import mujoco
import numpy as np

from processes.osc.model import CassieModel


def test_standing_pose_closes_rods_with_unloaded_springs_and_flat_feet(sim_model, q_stand):
    cm = CassieModel(sim_model)
    cm.update(q_stand, np.zeros(cm.nv))
    assert np.abs(cm.rod_residual[~cm.eq_planar]).max() < 1e-9
    assert np.abs(cm.p_contact[:, 2]).max() < 1e-9  # both blades flat on z = 0
    assert np.abs(q_stand[cm.spring_qpos]).max() < 1e-9
    assert abs(q_stand[2] - 0.95) < 1e-12


def test_holonomic_rows_are_independent_and_jdot_v_terms_match_finite_differences(
        sim_model, q_stand):
    cm = CassieModel(sim_model)
    rng = np.random.default_rng(0)
    v = rng.normal(size=cm.nv)  # any v, not only one satisfying the closures
    cm.update(q_stand, v)
    assert np.linalg.matrix_rank(cm.Jh) == 14
    assert np.linalg.svd(cm.Jh, compute_uv=False)[-1] > 1e-2
    Jh0, a0 = cm.Jh.copy(), cm.Jh_dot_v.copy()
    Jcom0, c0 = cm.J_com.copy(), cm.com_dot_v.copy()
    # contact points: the material point of the foot at the capsule's lowest point
    jd = np.zeros((3, cm.nv))
    for i in range(4):
        mujoco.mj_jacDot(cm.m, cm.d, jd, None, cm.p_contact[i], int(cm.foot_body[i // 2]))
        assert np.abs(jd @ v - cm.Jc_dot_v[3 * i : 3 * i + 3]).max() < 1e-9
    eps = 1e-6
    q2 = q_stand.copy()
    mujoco.mj_integratePos(cm.m, q2, v, eps)
    cm.update(q2, v)
    # d/dt (J v) at fixed v is Jdot v
    assert np.abs((cm.Jh - Jh0) @ v / eps - a0).max() < 1e-3 * max(1.0, np.abs(a0).max())
    assert np.abs((cm.J_com - Jcom0) @ v / eps - c0).max() < 1e-4
