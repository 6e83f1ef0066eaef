"""Moving obstacles (Table IV): the sim keeps foam cubes parked far away and drops each, at
its time after the holder's release, ahead of the pelvis; the robot's part of the state (the
ground truth, the packets) is the robot's alone."""

from __future__ import annotations

import numpy as np

from sim import terrain as terrain_mod
from sim.target_pc import DropsConfig, SimConfig, make_core


def test_cubes_wait_parked_then_land_where_and_when_they_are_dropped():
    drops = DropsConfig(after_release_s=(0.05, 0.3), side_m=(0.0, 0.5), ahead_m=0.9,
                        height_m=0.3, size_m=0.15)
    core = make_core(terrain_mod.flat(), SimConfig(drops=drops))
    assert (core.nq_robot, core.nv_robot) == (35, 32)
    assert core.m.nq == 35 + 2 * 7 and core.m.nv == 32 + 2 * 6
    parked = core.d.qpos[35:].copy()
    core.release_holder()
    core.step(60)  # 30 ms: nothing dropped yet, the parked cubes are still
    assert core.drops_done == []
    np.testing.assert_allclose(core.d.qpos[35:], parked, atol=1e-6)
    for _ in range(2000):  # to 1.03 s: both dropped and at rest on the ground (drops are
        core.step(1)  # checked per step call, as the sim node makes them: one per tick)
    assert [round(t, 4) for t, _, _ in core.drops_done] == [0.05, 0.3]
    (p0, s0), (p1, s1) = core.cube_states()
    assert abs(p0[0] - 0.9) < 0.05 and abs(p0[1]) < 0.05 and abs(p1[1] - 0.5) < 0.05
    assert abs(p0[2] - 0.075) < 0.005 and abs(p1[2] - 0.075) < 0.005  # resting on the floor
    assert s0 < 0.01 and s1 < 0.01


def test_the_model_without_drops_has_no_cubes():
    core = make_core(terrain_mod.flat(), SimConfig())
    assert (core.nq_robot, core.nv_robot) == (core.m.nq, core.m.nv) == (35, 32)
    assert core.cube_states() == []
