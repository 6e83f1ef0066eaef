"""Closed loop in MuJoCo: the OSC walks on plans from an ALIP stand-in for MPFC.

The stand-in (processes/osc/standin_planner.py) is not MPFC: fixed step timing, flat ground,
deadbeat ALIP foot placement. These tests prove the OSC side: hand-over from standing, swing
and stance phases from the plan, touchdowns near the planned footsteps, no fall.
"""

from __future__ import annotations

import gc

import mujoco
import numpy as np
import pytest

from lcmtypes import command_t
from processes.osc.controller import SAFE, STANDING, WALKING, OscController
from processes.osc.model import CassieModel
from processes.osc.standin_planner import StandInPlanner


def _walk(sim_model, q_stand, seconds: float, vx: float, stand_at: float = 1e9) -> dict:
    m = sim_model
    d = mujoco.MjData(m)
    d.qpos[:] = q_stand
    mujoco.mj_forward(m, d)
    osc = OscController()
    planner = StandInPlanner(CassieModel(m), vdes=(vx, 0.0))
    cmd = command_t()
    cmd.mode = 1  # stand first, then ask to walk
    plan = None
    z_min = 10.0
    modes = set()
    touchdowns = []  # (planned target, actual foot position) at each planned touchdown
    last_gs = None
    lift = 0.0
    yaw_max = 0.0
    t_stand = None
    x_at_1s = 0.0
    gc_was = gc.isenabled()
    gc.disable()
    try:
        for k in range(round(seconds / m.opt.timestep)):
            t = float(d.time)
            if t >= 0.25:
                cmd.mode = 0 if t < stand_at else 1
                if k % 10 == 0:  # planner at 200 Hz
                    prev = plan
                    plan = planner.plan(t, d.qpos, d.qvel)
                    if prev is not None and prev.gait_state in (0, 1) and plan.gait_state in (2, 3):
                        touchdowns.append((np.array(prev.next_footstep_world),
                                           np.array(plan.stance_foot_world)))
                    last_gs = plan.gait_state
            # the operator steers: yaw rate command against the heading error (command_t)
            cmd.yaw_rate = -2.0 * osc.model.pelvis_yaw() if k > 0 else 0.0
            u, dbg = osc.update(t, d.qpos, d.qvel, plan, cmd)
            modes.add(dbg.mode)
            if dbg.mode == STANDING and t > stand_at and t_stand is None:
                t_stand = t
            if t >= 1.5:
                yaw_max = max(yaw_max, abs(osc.model.pelvis_yaw()))
            assert dbg.mode != SAFE, dbg.status
            assert np.all(np.isfinite(u)) and np.all(np.abs(u) <= osc.model.u_max + 1e-9)
            d.ctrl[:] = u / osc.model.gear
            mujoco.mj_step(m, d)
            z_min = min(z_min, float(d.qpos[2]))
            if k == round(1.0 / m.opt.timestep):
                x_at_1s = float(d.qpos[0])
            if last_gs in (0, 1) and osc.walking.phase is not None:
                sw = 1 - osc.walking.phase.stance
                lift = max(lift, float(osc.model.foot_center(sw)[2]))
    finally:
        if gc_was:
            gc.enable()
    return {"z_min": z_min, "modes": modes, "touchdowns": touchdowns, "lift": lift,
            "x": float(d.qpos[0]), "z_end": float(d.qpos[2]), "yaw_max": yaw_max,
            "speed_after_1s": (float(d.qpos[0]) - x_at_1s) / (seconds - 1.0),
            "t_stand": t_stand, "final_speed": float(np.linalg.norm(d.qvel[0:3]))}


def test_osc_walks_forward_on_standin_plans_3s_without_falling(sim_model, q_stand):
    r = _walk(sim_model, q_stand, 3.0, vx=0.3)
    assert r["modes"] == {STANDING, WALKING}  # standing hand-over, then walking
    assert r["z_min"] > 0.8  # never close to a fall (pelvis starts at 0.95 m)
    assert len(r["touchdowns"]) >= 6  # 0.4 s steps
    assert r["lift"] > 0.05  # the swing foot really leaves the ground
    assert r["x"] > 0.3  # forward progress
    assert 0.15 < r["speed_after_1s"] < 0.5, r["speed_after_1s"]  # about the commanded 0.3 m/s
    assert r["yaw_max"] < 0.3  # heading held with the steering command
    # the swing foot lands where the plan asked (within 6 cm horizontally)
    err = [np.linalg.norm(a[:2] - b[:2]) for a, b in r["touchdowns"]]
    assert np.median(err) < 0.06, err


@pytest.mark.slow
def test_osc_steps_in_place_8s_without_falling(sim_model, q_stand):
    r = _walk(sim_model, q_stand, 8.0, vx=0.0)
    assert r["z_min"] > 0.8
    assert len(r["touchdowns"]) >= 18
    # the stand-in has no position feedback: stepping in place drifts, but slowly
    assert abs(r["speed_after_1s"]) < 0.2
