"""The compiled (numba) paths of the OSC against straightforward references built from
MuJoCo's own functions and dense numpy algebra: a dropped or wrong term fails these."""

from __future__ import annotations

import mujoco
import numpy as np

from processes.osc.model import CassieModel


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
