"""The sim sends its state between the two halves of a physics step (mj_step2, send,
mj_step1 for the next): the trajectory is bit for bit the one of mj_step, holder release
and push included."""

from __future__ import annotations

import mujoco
import numpy as np

from sim import terrain as terrain_mod
from sim.target_pc import PushConfig, SimConfig, make_core


def test_prepared_steps_give_the_mj_step_trajectory_bit_for_bit() -> None:
    cfg = SimConfig(push=PushConfig(after_release_s=0.05, force_n=(0.0, 80.0, 0.0),
                                    duration_s=0.02))
    split = make_core(terrain_mod.flat(), cfg)
    plain = make_core(terrain_mod.flat(), cfg)
    rng = np.random.default_rng(3)
    for k in range(400):
        torque = rng.normal(0.0, 5.0, len(split.idx.gear))
        for core in (split, plain):
            core.command(torque)  # the first nonzero command releases the holder
        split.step()
        sent = split.d.sensordata.copy()  # what the state packet reads (the IMU)
        split.prepare()  # the next step's first half, as the real-time tick does
        # the reference: MuJoCo's own mj_step with the same controls and forces
        if plain.release_time is not None:
            plain._apply_push(cfg.push)
        np.divide(plain.torque_cmd, plain.idx.gear, out=plain.d.ctrl)
        mujoco.mj_step(plain.m, plain.d)
        assert np.array_equal(split.d.qpos, plain.d.qpos), k
        assert np.array_equal(split.d.qvel, plain.d.qvel), k
        assert np.array_equal(sent, plain.d.sensordata), k
    assert not split.holder_engaged and split.release_time is not None
