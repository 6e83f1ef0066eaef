"""The sim's compiled 2 kHz path gives what its numpy code did, bit for bit: the state packet
(one compiled fill of every field, status and header), the command (torques, controls, the
holder's release on the first nonzero one) and the watchdog's zeroed controls, through
saturating torques, watchdog trips, catch-up steps, the holder's release and a push."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from runtime.cassie_packets import OutputPacket, encode_input
from sim.target_pc import (
    HolderConfig,
    PushConfig,
    SimConfig,
    SimCore,
    TargetPC,
    make_core,
)
from sim.terrain import flat


def numpy_fill(tpc: TargetPC, ref: OutputPacket) -> bytes:
    """The state packet as ``SimCore.fill_output`` and ``TargetPC.encode_state`` wrote it
    with numpy (reference), for the seq/ack the last ``encode_state`` used."""
    core = tpc.core
    d, i = core.d, core.idx
    ref.utime = round(d.time * 1e6)
    ref.imu_quat[:] = d.qpos[3:7]
    ref.imu_gyro[:] = d.qvel[3:6]
    ref.imu_accel[:] = d.sensordata[i.accel_adr:i.accel_adr + 3]
    d.qpos.take(i.motor_qpos, out=ref.motor_pos)
    d.qvel.take(i.motor_dof, out=ref.motor_vel)
    np.multiply(d.actuator_force, i.gear, out=ref.motor_torque)
    d.qpos.take(i.joint_qpos, out=ref.joint_pos)
    d.qvel.take(i.joint_dof, out=ref.joint_vel)
    if tpc.mode == "realtime":
        ref.task_time_s = tpc.stats.last_task_s
        ref.overruns = tpc.stats.overruns
    ref.status = tpc.status_bits()
    return bytes(ref.encode(tpc.link.own_seq, tpc.link.last_peer_seq))


class NumpyCore:
    """SimCore's command and step as numpy code (reference) on an MjData of its own."""

    def __init__(self, core: SimCore) -> None:
        self.core = core
        self.d = mujoco.MjData(core.m)
        mujoco.mj_copyData(self.d, core.m, core.d)
        self.torque_cmd = np.zeros(10)
        self.last: float | None = None

    def command(self, torque: np.ndarray) -> None:
        self.torque_cmd[:] = torque
        self.last = float(self.d.time)

    def step(self, n: int) -> None:
        c = self.core
        for _ in range(n):
            tripped = self.last is None or (
                self.d.time - self.last >= c.cfg.watchdog_s - 0.25 * c.dt)
            if tripped:
                self.d.ctrl[:] = 0.0
            else:
                np.divide(self.torque_cmd, c.idx.gear, out=self.d.ctrl)
            mujoco.mj_step(c.m, self.d)


def _script(rng: np.random.Generator, k: int) -> tuple[np.ndarray | None, int]:
    """Step k's command (None: none came) and physics steps: torques up to 3x the motors'
    limits (the controls saturate), gaps of 15 ms (the watchdog trips), catch-up steps."""
    steps = 3 if k % 97 == 50 else 1
    if 120 <= k < 150 or 300 <= k < 340:
        return None, steps
    if k % 5 == 3:
        return None, steps  # the last torque is reused
    return rng.uniform(-3.0, 3.0, 10) * np.array([112.5, 112.5, 195.2, 195.2, 45.0] * 2), steps


@pytest.mark.parametrize("mode", ["realtime", "lockstep"])
def test_the_compiled_path_gives_the_numpy_packets_controls_and_states(mode: str) -> None:
    cfg = SimConfig(push=PushConfig(after_release_s=0.02, force_n=(30.0, -60.0, 0.0),
                                    duration_s=0.03))
    tpc = TargetPC(make_core(flat(), cfg), mode)
    core = tpc.core
    ref_core, ref_pkt = NumpyCore(core), OutputPacket()
    rng = np.random.default_rng(11)
    tripped_seen = saturated_seen = 0
    for k in range(400):
        torque, steps = _script(rng, k)
        tpc.stats.last_task_s = 1e-4 * (k % 7 + 1)  # the wall-clock figures of a real-time tick
        tpc.stats.overruns = 3 * k
        tpc.stats.slower_than_realtime = k % 11 == 0
        if torque is not None:
            assert tpc.take(encode_input(k, tpc.link.own_seq, torque))
            ref_core.command(torque)
            ref_core.d.eq_active[:] = core.d.eq_active  # the holder lets go in both
            assert np.array_equal(core.torque_cmd, torque)
            assert np.array_equal(core.d.ctrl, torque / core.idx.gear)
        if core.release_time is not None:  # the push acts on both, from the core's window
            core._apply_push(cfg.push)
            ref_core.d.xfrc_applied[:] = core.d.xfrc_applied
        core.step(steps)
        ref_core.step(steps)
        out = bytes(tpc.encode_state())
        assert out == numpy_fill(tpc, ref_pkt), k
        assert np.array_equal(core.d.qpos, ref_core.d.qpos), k
        assert np.array_equal(core.d.qvel, ref_core.d.qvel), k
        assert np.array_equal(core.d.ctrl, ref_core.d.ctrl), k
        tripped_seen += core.torque_zeroed
        saturated_seen += bool((np.abs(core.d.ctrl) > core.m.actuator_ctrlrange[:, 1]).any())
        core.prepare()
    assert not core.holder_engaged and tripped_seen > 20 and saturated_seen > 100
    pkt = OutputPacket().decode(out)
    assert (pkt.task_time_s > 0) == (mode == "realtime") and pkt.utime == core.utime


@pytest.mark.parametrize(("torque", "releases"), [
    (np.zeros(10), False), (np.full(10, -0.0), False), (np.eye(10)[3] * 1e-300, True),
    (np.full(10, np.nan), True), ([0.0] * 9 + [2.0], True)])
def test_only_a_nonzero_command_releases_the_holder(torque: object, releases: bool) -> None:
    core = make_core(flat(), SimConfig(holder=HolderConfig(release_on="first_nonzero_command")))
    core.command(torque)  # type: ignore[arg-type]
    assert core.holder_engaged != releases
    want = np.asarray(torque, dtype=float)
    assert np.array_equal(core.torque_cmd, want, equal_nan=True)
    assert np.array_equal(core.d.ctrl, want / core.idx.gear, equal_nan=True)


def test_a_command_of_the_wrong_length_is_refused() -> None:
    core = make_core(flat())
    with pytest.raises(ValueError):
        core.command(np.zeros(9))
    assert core.commands == 0
