"""Leg kinematics from the 18 measured joints: rods solved in closed form, feet as in MuJoCo."""

from __future__ import annotations

import mujoco
import numpy as np

from processes.state_estimator.kinematics import LegKinematics
from runtime.cassie_packets import OutputPacket, encode_input
from tests.state_estimator.scripted import pd_torque, sim_settings


def _closure_velocity(m: mujoco.MjModel, d: mujoco.MjData) -> np.ndarray:
    """Relative velocity (m/s) of each connect constraint's two points, for d.qpos/d.qvel."""
    mujoco.mj_kinematics(m, d)
    mujoco.mj_comPos(m, d)
    out = []
    jp = np.zeros((3, m.nv))
    for i in range(m.neq):
        b1, b2 = m.eq_obj1id[i], m.eq_obj2id[i]
        vs = []
        for b, off in ((b1, m.eq_data[i, 0:3]), (b2, m.eq_data[i, 3:6])):
            p = d.xpos[b] + d.xmat[b].reshape(3, 3) @ off
            mujoco.mj_jac(m, d, jp, None, p, int(b))
            vs.append(jp @ d.qvel)
        out.append(vs[0] - vs[1])
    return np.array(out)


def test_rods_close_and_feet_match_mujoco_during_a_squat():
    from sim.target_pc import TargetPC, make_core

    core = make_core(config=sim_settings().sim)
    tpc = TargetPC(core)
    kin = LegKinematics(core.m)
    d_ref = mujoco.MjData(core.m)
    pkt = OutputPacket()
    q0 = core.q_start[core.idx.motor_qpos].copy()
    checked = 0
    for k in range(1200):
        d = core.d
        tau = pd_torque("squat", core.time + 0.5, q0, d.qpos[core.idx.motor_qpos],
                        d.qvel[core.idx.motor_dof])
        pkt.decode(bytes(tpc.realtime_cycle(encode_input(k, 0, tau))))
        if k % 100 != 99:
            continue
        checked += 1
        kin.update(pkt.motor_pos, pkt.motor_vel, pkt.joint_pos, pkt.joint_vel)
        # the sim's own state, pelvis moved to the origin: feet must coincide
        d_ref.qpos[:] = d.qpos
        d_ref.qpos[0:7] = (0, 0, 0, 1, 0, 0, 0)
        d_ref.qvel[:] = d.qvel
        d_ref.qvel[0:6] = 0.0
        mujoco.mj_kinematics(core.m, d_ref)
        for side, g in enumerate(core.idx.foot_geoms):
            np.testing.assert_allclose(kin.foot_pos[side], d_ref.geom_xpos[g], atol=1e-9)
        # measured joints are copied, rods solved: closures hold to the sim's own accuracy
        np.testing.assert_allclose(kin.q[kin.motor_qpos], d.qpos[kin.motor_qpos])
        np.testing.assert_allclose(kin.q[kin.joint_qpos], d.qpos[kin.joint_qpos])
        sim_closure = np.abs(
            np.array([np.linalg.norm(x) for x in _closure_residual(core.m, d_ref)])).max()
        assert kin.closure_residual().max() <= sim_closure + 2e-4
        # plantar rods are hinges: unique, must match the sim's angle and rate
        for qa, da in zip(kin._pla_qpos, kin._pla_dof, strict=True):
            assert abs(kin.q[qa] - d.qpos[qa]) < 5e-3
            assert abs(kin.v[da] - d.qvel[da]) < 0.05 + 0.05 * abs(d.qvel[da])
        # rod rates cancel every closure's relative velocity but the part along the rod that
        # no rod rate can change (the sim's soft closures stretch): never worse than the sim
        d_ref.qpos[:] = d.qpos
        d_ref.qvel[:] = d.qvel
        sim_vel = np.linalg.norm(_closure_velocity(core.m, d_ref), axis=1)
        d_ref.qpos[:] = kin.q
        d_ref.qvel[:] = kin.v
        ours = np.linalg.norm(_closure_velocity(core.m, d_ref), axis=1)
        assert (ours <= sim_vel + 1e-4).all()
    assert checked == 12


def _closure_residual(m: mujoco.MjModel, d: mujoco.MjData) -> list[np.ndarray]:
    out = []
    for i in range(m.neq):
        b1, b2 = m.eq_obj1id[i], m.eq_obj2id[i]
        p1 = d.xpos[b1] + d.xmat[b1].reshape(3, 3) @ m.eq_data[i, 0:3]
        p2 = d.xpos[b2] + d.xmat[b2].reshape(3, 3) @ m.eq_data[i, 3:6]
        out.append(p1 - p2)
    return out
