"""Closed loop in MuJoCo: the standing controller holds Cassie up (2 kHz, lockstep)."""

from __future__ import annotations

import gc

import mujoco
import numpy as np

from processes.osc.controller import STANDING, OscController


def test_standing_controller_holds_cassie_5s_with_under_2cm_height_drift(sim_model, q_stand):
    m = sim_model
    d = mujoco.MjData(m)
    d.qpos[:] = q_stand
    mujoco.mj_forward(m, d)
    osc = OscController()
    gear = osc.model.gear
    z0 = float(d.qpos[2])
    steps = round(5.0 / m.opt.timestep)
    z_min = z_max = z0
    feet = (m.body("left-foot").id, m.body("right-foot").id)
    f6 = np.zeros(6)
    fz = np.zeros((steps, 2))  # normal force on each foot
    gc_was = gc.isenabled()
    gc.disable()
    try:
        for k in range(steps):
            u, dbg = osc.update(float(d.time), d.qpos, d.qvel)  # perfect state, lockstep
            assert dbg.mode == STANDING, dbg.status
            assert np.all(np.abs(u) <= osc.model.u_max + 1e-9)
            d.ctrl[:] = u / gear  # joint-side torque -> motor ctrl
            mujoco.mj_step(m, d)
            z = float(d.qpos[2])
            z_min, z_max = min(z_min, z), max(z_max, z)
            for i in range(d.ncon):
                c = d.contact[i]
                for side, body in enumerate(feet):
                    if body in (m.geom_bodyid[c.geom1], m.geom_bodyid[c.geom2]):
                        mujoco.mj_contactForce(m, d, i, f6)
                        fz[k, side] += f6[0]
    finally:
        if gc_was:
            gc.enable()
    assert z_min > 0.6  # no fall
    assert abs(float(d.qpos[2]) - z0) < 0.02
    assert z_max - z_min < 0.02
    # stayed level and did not wander
    assert np.linalg.norm(d.qpos[0:2] - q_stand[0:2]) < 0.03
    assert abs(d.qpos[4]) < 0.02 and abs(d.qpos[5]) < 0.02  # quaternion x, y: roll/pitch small
    # after the start-up transient: both feet stay loaded, without ringing the leaf springs
    settled = fz[round(1.0 / m.opt.timestep) :]
    assert settled.min() > 50.0
    assert settled.std(axis=0).max() < 15.0
