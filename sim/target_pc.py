"""The target PC without transport: physics, watchdog, pelvis holder, packets, loop accounting.

``SimCore`` owns the MuJoCo state and steps it in place with the newest joint-side torques;
``TargetPC`` adds the UDP protocol (``runtime.cassie_packets``) and the two modes:

* real time: one physics step per 0.5 ms tick; the last torque is reused when no command
  arrived, and torques drop to zero ``watchdog_s`` (10 ms) of *sim* time after the last one;
* lockstep: step only when a command answers the newest state (its ``ack`` equals the state's
  ``seq``); a missing answer is a reported timeout and the state is sent again.

Nothing here reads the wall clock except ``LoopStats``, which only reports; so the state of two
runs fed the same commands is bit-identical.

The 2 kHz path is built to cost little more than MuJoCo's own step: a command is taken in one
compiled call (torques, and the controls they give, written in place), the whole state packet
is filled in another (``_fill_output``), and per physics step only the watchdog test runs in
Python around ``mj_step1``/``mj_step2``.
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, field
from typing import Literal, get_args

import mujoco
import numba
import numpy as np

from runtime.cassie_packets import (
    FLAG_RELEASE_HOLDER,
    INPUT_SIZE,
    STATUS_HOLDER_ENGAGED,
    STATUS_LOCKSTEP,
    STATUS_SLOWER_THAN_REALTIME,
    STATUS_WATCHDOG_TRIPPED,
    TOKEN_AT,
    InputPacket,
    LinkCounter,
    OutputPacket,
    PacketError,
    float_block,
)
from runtime.pairing import DEFAULT_TOKEN, token_bytes
from runtime.params import spec
from sim.model import CassieIndices, build_model, cube_bodies, robot_size, standing_pose
from sim.terrain import Terrain

log = logging.getLogger(__name__)

ReleaseOn = Literal["first_command", "first_nonzero_command", "manual"]
RELEASE_ON: tuple[str, ...] = get_args(ReleaseOn)  # the values a config may name


@dataclass(frozen=True)
class HolderConfig:
    """A soft weld holding the pelvis at its start pose until the controller takes over.

    The weld is a MuJoCo equality constraint to a mocap body (no Python in the step loop);
    its softness is MuJoCo's ``solref``: a time constant and a damping ratio. At 10 ms the
    pelvis sags about 1 mm under the robot's weight.
    """

    enabled: bool = True
    timeconst_s: float = spec(0.01, lo=0.001, hi=1.0, unit="s")
    dampratio: float = spec(1.0, lo=0.1, hi=10.0)
    release_on: ReleaseOn = "first_nonzero_command"


@dataclass(frozen=True)
class PushConfig:
    """An external force on the pelvis (world frame, N) for ``duration_s``, ``after_release_s``
    of sim time after the holder lets go: a shove for push-recovery tests, or one that knocks
    the robot over to check that a launch reports the fall."""

    after_release_s: float = spec(lo=0.0, unit="s")  # (required: no default)
    force_n: tuple[float, float, float] = spec(lo=-1e4, hi=1e4, unit="N")  # (required)
    duration_s: float = spec(0.1, lo=5e-4, hi=10.0, unit="s")


@dataclass(frozen=True)
class DropsConfig:
    """Foam cubes dropped in front of the robot (the paper's moving obstacles, Section VIII-D-4
    and Table IV): the i-th at ``after_release_s[i]`` of sim time after the holder lets go,
    ``ahead_m`` in front of the pelvis along its heading and ``side_m[i % len]`` to its left,
    its bottom ``height_m`` above the lower foot, at rest, turned about z by a seeded angle.
    The cubes wait parked far away until then (``sim.model.build_model(cubes=...)``)."""

    after_release_s: tuple[float, ...] = spec(lo=0.0, unit="s")  # (required: no default)
    ahead_m: float = spec(0.9, lo=0.0, hi=5.0, unit="m")
    side_m: tuple[float, ...] = spec((0.0,), lo=-2.0, hi=2.0, unit="m")
    height_m: float = spec(0.6, lo=0.0, hi=3.0, unit="m")
    size_m: float = spec(0.15, lo=0.02, hi=1.0, unit="m")
    seed: int = spec(0, lo=0)


@dataclass(frozen=True)
class SimConfig:
    """Physics and start-up settings of the target PC."""

    watchdog_s: float = 0.010
    impratio: float = 10.0
    pelvis_height: float = 0.95
    foot_y: float = 0.135
    holder: HolderConfig = field(default_factory=HolderConfig)
    push: PushConfig | None = None
    drops: DropsConfig | None = None


class SimCore:
    """MuJoCo Cassie stepped in place with joint-side torques, a sim-time watchdog and a holder."""

    def __init__(self, model: mujoco.MjModel, config: SimConfig | None = None,
                 start_z: float = 0.0) -> None:
        self.m = model
        self.cfg = config or SimConfig()
        self.d = mujoco.MjData(model)
        self.idx = CassieIndices.of(model)
        #: the robot's part of qpos and qvel (the model may hold obstacle cubes after it)
        self.nq_robot, self.nv_robot = robot_size(model)
        self._cubes = cube_bodies(model)
        drops = self.cfg.drops
        if drops is not None and len(drops.after_release_s) > len(self._cubes):
            raise ValueError(f"{len(drops.after_release_s)} drops but the model has "
                             f"{len(self._cubes)} cubes: build it with "
                             "build_model(cubes=len(after_release_s))")
        self.dt = float(model.opt.timestep)
        self.q_start = standing_pose(model, self.cfg.pelvis_height, start_z, self.cfg.foot_y)
        #: newest command, N m at the joint (set it with ``command``: the controls follow it)
        self.torque_cmd = np.zeros(len(self.idx.gear))
        d = self.d  # views made once: the 2 kHz path only reads and writes existing arrays
        self._qpos, self._qvel, self._ctrl = d.qpos, d.qvel, d.ctrl
        self._sensordata, self._actuator_force = d.sensordata, d.actuator_force
        self._gear = np.ascontiguousarray(self.idx.gear, dtype=np.float64)
        self._table = _output_table(self.idx)
        #: sim time after the last command at which the watchdog zeroes the torques
        self._watchdog_after_s = self.cfg.watchdog_s - 0.25 * self.dt
        self._ctrl_live = False  # d.ctrl holds torque_cmd / gear (else zeros)
        self._prepared = False
        self.reset()
        _warm_kernels()

    # -- state -----------------------------------------------------------------------------
    def reset(self, qpos: np.ndarray | None = None) -> None:
        """Back to the standing pose (or ``qpos``), at rest, holder engaged if configured."""
        mujoco.mj_resetData(self.m, self.d)
        self.d.qpos[:] = self.q_start if qpos is None else qpos
        if self.idx.holder_eq < 0 and self.cfg.holder.enabled:
            raise ValueError("this model has no pelvis holder: build it with sim.model.build_model")
        if self.idx.holder_eq >= 0:
            self.d.mocap_pos[self.idx.holder_mocap] = self.d.qpos[0:3]
            self.d.mocap_quat[self.idx.holder_mocap] = self.d.qpos[3:7]
            self.d.eq_active[self.idx.holder_eq] = self.cfg.holder.enabled
        mujoco.mj_forward(self.m, self.d)
        self._prepared = True  # mj_forward did what mj_step1 would
        self._ctrl_live = False  # mj_resetData zeroed d.ctrl
        self.torque_cmd[:] = 0.0
        self.last_command_time: float | None = None
        self.holder_engaged = self.cfg.holder.enabled
        self.release_time: float | None = None if self.holder_engaged else 0.0
        self._push_window: tuple[float, float] | None = None
        self.pushing = False
        #: per dropped cube: (sim time of the drop, world x, y of where it was let go)
        self.drops_done: list[tuple[float, float, float]] = []
        self.commands = 0
        self.steps = 0
        self.torque_zeroed = True  # the last step applied zeros because of the watchdog
        self.zero_torque_steps = 0  # steps the watchdog (or no command yet) held at zero

    @property
    def time(self) -> float:
        return float(self.d.time)

    @property
    def utime(self) -> int:
        return round(self.d.time * 1e6)

    @property
    def watchdog_tripped(self) -> bool:
        """True when the torques applied now are zeros because commands stopped (or never came)."""
        last = self.last_command_time
        return last is None or self.d.time - last >= self._watchdog_after_s

    # -- inputs ----------------------------------------------------------------------------
    def command(self, torque: np.ndarray, flags: int = 0) -> None:
        """A new joint-side torque command (N m), received at the current sim time: the
        newest torques, and the controls they give (``torque / gear``; MuJoCo clamps them)."""
        if type(torque) is not np.ndarray:
            torque = np.asarray(torque, dtype=np.float64)
        nonzero = _set_command(torque, self.torque_cmd, self._gear, self._ctrl)
        self._ctrl_live = True
        self.last_command_time = float(self.d.time)
        self.commands += 1
        if self.holder_engaged:
            rel = self.cfg.holder.release_on
            if flags & FLAG_RELEASE_HOLDER or rel == "first_command" or (
                    rel == "first_nonzero_command" and nonzero):
                self.release_holder()

    def release_holder(self) -> None:
        """Let go of the pelvis (idempotent)."""
        if self.holder_engaged:
            log.info("pelvis holder released at t=%.4f s", self.d.time)
            self.release_time = float(self.d.time)
        self.holder_engaged = False
        if self.idx.holder_eq >= 0:
            self.d.eq_active[self.idx.holder_eq] = 0
            self._prepared = False  # the constraints are made in mj_step1: make them again

    # -- stepping --------------------------------------------------------------------------
    def step(self, n: int = 1) -> None:
        """Advance ``n`` physics steps with the newest torque (zeros once the watchdog trips)."""
        d, m = self.d, self.m
        push = self.cfg.push
        if push is not None and self.release_time is not None:
            self._apply_push(push)
        drops = self.cfg.drops
        if (drops is not None and self.release_time is not None
                and len(self.drops_done) < len(drops.after_release_s)):
            self._apply_drops(drops)
        for _ in range(n):
            last = self.last_command_time  # the watchdog (``watchdog_tripped``), inline
            zeroed = last is None or d.time - last >= self._watchdog_after_s
            self.torque_zeroed = zeroed
            # d.ctrl is torque_cmd / gear since the last command (MuJoCo reads it and never
            # writes it), zeros while the watchdog holds: rewritten only when that changes
            if zeroed:
                self.zero_torque_steps += 1
                if self._ctrl_live:
                    self._ctrl[:] = 0.0
                    self._ctrl_live = False
            elif not self._ctrl_live:
                np.divide(self.torque_cmd, self._gear, out=self._ctrl)
                self._ctrl_live = True
            # mj_step = mj_step1 (positions, velocities, collisions) + mj_step2 (actuation,
            # acceleration, integration), bit for bit with the Euler integrator; step1 for the
            # next step may have run already (``prepare``), after the state went out
            if not self._prepared:
                mujoco.mj_step1(m, d)
            mujoco.mj_step2(m, d)
            self._prepared = False
            self.steps += 1

    def prepare(self) -> None:
        """Run the first half of the next physics step now (``mj_step1``), so that the state
        packet can go out as soon as the integration is done and this work overlaps with the
        NUC's; the physics is the same as stepping with ``mj_step``."""
        if not self._prepared:
            mujoco.mj_step1(self.m, self.d)
            self._prepared = True

    def _apply_push(self, push: PushConfig) -> None:
        """The configured shove on the pelvis, inside its window of sim time (per step call:
        the window is resolved to the 0.5 ms step)."""
        t = self.d.time - (self.release_time or 0.0)
        on = push.after_release_s <= t < push.after_release_s + push.duration_s
        if on != self.pushing:
            self.d.xfrc_applied[self.idx.pelvis_body, :3] = push.force_n if on else 0.0
            if on:
                log.info("pushing the pelvis with %s N for %.3f s at t=%.3f s", push.force_n,
                         push.duration_s, self.d.time)
            self.pushing = on

    def _apply_drops(self, drops: DropsConfig) -> None:
        """Let the next cube go once its time after the release has come (per step call)."""
        i = len(self.drops_done)
        if self.d.time - (self.release_time or 0.0) < drops.after_release_s[i]:
            return
        d, m = self.d, self.m
        w, x, y, z = d.qpos[3:7]
        yaw = math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
        c, s = math.cos(yaw), math.sin(yaw)
        side = drops.side_m[i % len(drops.side_m)]
        px = float(d.qpos[0]) + c * drops.ahead_m - s * side
        py = float(d.qpos[1]) + s * drops.ahead_m + c * side
        radius = m.geom_size[list(self.idx.foot_geoms), 0]
        ground = min(float(d.geom_xpos[g, 2]) for g in self.idx.foot_geoms) - float(radius[0])
        turn = np.random.default_rng((drops.seed, i)).uniform(-math.pi, math.pi)
        j = int(m.body_jntadr[self._cubes[i]])
        qa, va = int(m.jnt_qposadr[j]), int(m.jnt_dofadr[j])
        d.qpos[qa:qa + 7] = (px, py, ground + drops.height_m + 0.5 * drops.size_m,
                             math.cos(turn / 2), 0.0, 0.0, math.sin(turn / 2))
        d.qvel[va:va + 6] = 0.0
        self._prepared = False  # the state changed after mj_step1
        self.drops_done.append((float(d.time), px, py))
        log.info("dropped cube %d at (%.2f, %.2f) at t=%.3f s", i, px, py, d.time)

    def cube_states(self) -> list[tuple[np.ndarray, float]]:
        """Each dropped cube's world position and speed (m/s), in drop order."""
        out = []
        for i in range(len(self.drops_done)):
            j = int(self.m.body_jntadr[self._cubes[i]])
            qa, va = int(self.m.jnt_qposadr[j]), int(self.m.jnt_dofadr[j])
            out.append((self.d.qpos[qa:qa + 3].copy(),
                        float(np.linalg.norm(self.d.qvel[va:va + 3]))))
        return out

    # -- outputs ---------------------------------------------------------------------------
    def fill_output(self, pkt: OutputPacket, status: int, seq: int, ack: int,
                    task_time_s: float | None = None, overruns: int = 0) -> None:
        """Write the whole robot-output packet of the current state in one compiled call: the
        fields the physics gives (utime, IMU, motors, passive joints; ``_output_table``), and
        the target PC's ``status``, header (``seq``, ``ack``) and, when ``task_time_s`` is
        given, its task time and ``overruns`` (left as they are otherwise)."""
        _fill_output(self._qpos, self._qvel, self._sensordata, self._actuator_force, self._gear,
                     self._table, pkt.floats, pkt.bytes_array, self.d.time,
                     -1.0 if task_time_s is None else task_time_s, overruns, status, seq, ack)

    def foot_contacts(self) -> tuple[bool, bool]:
        """Whether each foot's collision geom touches anything now."""
        d = self.d
        n = d.ncon
        if n == 0:
            return (False, False)
        g1 = d.contact.geom1[:n]
        g2 = d.contact.geom2[:n]
        left, right = self.idx.foot_geoms
        return (bool(np.any((g1 == left) | (g2 == left))),
                bool(np.any((g1 == right) | (g2 == right))))

    def com_and_velocity(self) -> tuple[np.ndarray, np.ndarray]:
        """Whole-robot centre of mass and its velocity (world)."""
        mujoco.mj_subtreeVel(self.m, self.d)
        b = self.idx.pelvis_body
        return self.d.subtree_com[b].copy(), self.d.subtree_linvel[b].copy()


class LoopStats:
    """Wall-clock accounting of a periodic loop: task time, overruns, real-time factor.

    ``record`` is called once per tick with the task time and how many slots the loop skipped
    since the previous tick; the real-time factor is sim time over wall time per window.
    """

    def __init__(self, period_s: float, window_s: float = 1.0, target_rtf: float = 1.0) -> None:
        self.period_s = period_s
        self.window_s = window_s
        #: the real-time factor asked for (profile ``rtf``): "slower than real time" is
        #: relative to it, and a tick's wall-clock period is period_s / target_rtf
        self.target_rtf = target_rtf
        self.ticks = 0
        self.overruns = 0
        self.last_task_s = 0.0
        self.max_task_s = 0.0
        self.rtf = 1.0
        self.slower_than_realtime = False
        self.slow_windows = 0
        self._w0_wall: float | None = None
        self._w0_sim = 0.0

    def record(self, task_s: float, sim_time: float, skipped: int = 0,
               wall: float | None = None) -> None:
        """One tick: its task time, the sim time after it, the slots skipped before it, and
        the wall clock now (``time.monotonic()`` when not given)."""
        self.ticks += 1
        self.last_task_s = task_s
        if task_s > self.max_task_s:
            self.max_task_s = task_s
        if task_s > self.period_s / self.target_rtf or skipped > 0:
            self.overruns += max(skipped, 1)
        now = time.monotonic() if wall is None else wall
        if self._w0_wall is None:
            self._w0_wall, self._w0_sim = now, sim_time
            return
        elapsed = now - self._w0_wall
        if elapsed >= self.window_s:
            self.rtf = (sim_time - self._w0_sim) / elapsed
            slow = self.rtf < 0.98 * self.target_rtf
            if slow:
                self.slow_windows += 1
                if not self.slower_than_realtime or self.slow_windows % 10 == 1:
                    log.warning("sim runs slower than real time: factor %.3f over the last "
                                "%.1f s (%d overruns so far)", self.rtf, elapsed, self.overruns)
            self.slower_than_realtime = slow
            self._w0_wall, self._w0_sim = now, sim_time


Mode = Literal["realtime", "lockstep"]


class TargetPC:
    """The target PC's packet logic around a ``SimCore``, for either mode; transport-free.

    Feed it received datagrams, get back the datagram to send (a view into a reused buffer:
    send it or copy it before the next call).
    """

    def __init__(self, core: SimCore, mode: Mode = "realtime", steps_per_command: int = 1,
                 token: int = DEFAULT_TOKEN) -> None:
        self.core = core
        #: the pairing token a torque packet must carry (``runtime.pairing.link_token``)
        self.token = token
        self._token = token_bytes(token)
        self.mode = mode
        self.steps_per_command = steps_per_command
        self.link = LinkCounter()
        self.inp = InputPacket()
        self.out = OutputPacket()
        self._realtime = mode == "realtime"
        self.stats = LoopStats(core.dt * (steps_per_command if mode == "lockstep" else 1))
        self.timeouts = 0  # lockstep: no answer within the timeout
        self.unanswered = 0  # lockstep: commands whose ack is not the newest state
        self.last_error = ""
        self._errors_logged = 0

    def receive(self, data: bytes | bytearray | memoryview) -> bool:
        """Decode and account one datagram; False (counted, never raised) if malformed."""
        inp = self.inp
        if data[TOKEN_AT:TOKEN_AT + 4] != self._token and len(data) == INPUT_SIZE:
            self._foreign(data)
            return False
        try:
            inp.decode(data)
        except PacketError as exc:
            self._rejected(exc)
            return False
        buf = inp.buffer
        self.link.on_receive(buf[0], buf[1])  # seq, ack
        return True

    def _foreign(self, data: bytes | bytearray | memoryview) -> None:
        """A torque packet from a bridge this target PC is not paired with: dropped."""
        self.link.foreign += 1
        other = int.from_bytes(bytes(data[TOKEN_AT:TOKEN_AT + 4]), "little")
        self.last_error = (f"torque packet with pairing token {other:#010x}, not this launch's "
                           f"{self.token:#010x}: from another stack or tool (dropped)")
        if self.link.foreign <= 10 or self.link.foreign % 1000 == 0:
            log.warning("foreign packet #%d: %s", self.link.foreign, self.last_error)

    def _rejected(self, exc: PacketError) -> None:
        self.link.on_error()
        self.last_error = str(exc)
        if self._errors_logged < 10 or self.link.malformed % 1000 == 0:
            self._errors_logged += 1
            log.warning("rejected packet #%d: %s", self.link.malformed, exc)

    def status_bits(self) -> int:
        c = self.core
        bits = 0
        if c.holder_engaged:
            bits |= STATUS_HOLDER_ENGAGED
        if c.torque_zeroed:
            bits |= STATUS_WATCHDOG_TRIPPED
        if self.stats.slower_than_realtime:
            bits |= STATUS_SLOWER_THAN_REALTIME
        if self.mode == "lockstep":
            bits |= STATUS_LOCKSTEP
        return bits

    def encode_state(self) -> memoryview:
        """The robot-output datagram of the current state, with the next own seq (a view of
        ``self.out.buffer``, which holds the same bytes)."""
        link, stats = self.link, self.stats
        seq = link.next_seq()
        if self._realtime:  # wall-clock figures would make lockstep runs differ
            self.core.fill_output(self.out, self.status_bits(), seq, link.last_peer_seq,
                                  stats.last_task_s, stats.overruns)
        else:
            self.core.fill_output(self.out, self.status_bits(), seq, link.last_peer_seq)
        return self.out.view

    def take(self, data: bytes | bytearray | memoryview) -> bool:
        """One received torque datagram: decoded, counted, and its torques made the newest
        command (False when malformed: counted, never raised)."""
        if not self.receive(data):
            return False
        inp = self.inp
        self.core.command(inp.torque, inp.flags)
        return True

    def realtime_cycle(self, data: bytes | bytearray | memoryview | None, steps: int = 1
                       ) -> memoryview:
        """One tick: take the newest command if any, step ``steps`` times (1 at 2 kHz), return
        the state (send it, then call ``core.prepare``)."""
        if data is not None:
            self.take(data)
        self.core.step(steps)
        return self.encode_state()

    def lockstep_cycle(self, data: bytes | bytearray | memoryview | None) -> memoryview | None:
        """Step only on a command answering the newest state; None means send nothing.

        ``data is None`` is a timeout: counted, reported, and the last state is sent again
        (same seq) in case it was lost.
        """
        if data is None:
            self.timeouts += 1
            if self.timeouts <= 10 or self.timeouts % 1000 == 0:
                log.warning("lockstep: no command answered state seq %d within the timeout "
                            "(%d timeouts); resending it", self.out.seq, self.timeouts)
            return self.out.view
        if not self.receive(data):
            return None
        if self.inp.ack != self.out.seq:
            self.unanswered += 1
            return None
        self.core.command(self.inp.torque, self.inp.flags)
        self.core.step(self.steps_per_command)
        return self.encode_state()

    def summary(self) -> str:
        c = self.core
        s = (f"{self.mode} t={c.time:.3f}s rtf={self.stats.rtf:.3f} "
             f"overruns={self.stats.overruns} {self.link.summary()}")
        if c.holder_engaged:
            s += " holder=on"
        if c.torque_zeroed:
            s += " watchdog=zero-torque"
        if self.mode == "lockstep":
            s += f" timeouts={self.timeouts} unanswered={self.unanswered}"
        if self.stats.slower_than_realtime:
            s += " SLOWER-THAN-REALTIME"
        return s


# -- compiled pieces of the 2 kHz path ---------------------------------------------------------

# what one row of ``_output_table`` copies: (source, index in it, destination)
_QPOS, _QVEL, _SENSOR, _TORQUE, _TASK, _UTIME, _OVERRUNS, _STATUS = range(8)


def _output_table(idx: CassieIndices) -> np.ndarray:
    """How the output packet is filled from MjData, one row per value: (source, index,
    destination). Floats go to ``OutputPacket.floats[destination]`` (``_QPOS``, ``_QVEL``,
    ``_SENSOR``: copied; ``_TORQUE``: ``actuator_force[i] * gear[i]``, the joint-side torque of
    the clamped controls of the last step; ``_TASK``: the task time), integers to byte offset
    ``destination`` (``_UTIME``: int64 ``round(time * 1e6)``; ``_OVERRUNS``, ``_STATUS``:
    uint32)."""
    a = idx.accel_adr
    src: dict[str, list[tuple[int, int]]] = {
        "imu_quat": [(_QPOS, i) for i in range(3, 7)],  # the IMU site is aligned with the pelvis
        "imu_gyro": [(_QVEL, i) for i in range(3, 6)],  # free-joint angular velocity: body frame
        "imu_accel": [(_SENSOR, i) for i in range(a, a + 3)],
        "motor_pos": [(_QPOS, int(i)) for i in idx.motor_qpos],
        "motor_vel": [(_QVEL, int(i)) for i in idx.motor_dof],
        "motor_torque": [(_TORQUE, k) for k in range(len(idx.gear))],
        "joint_pos": [(_QPOS, int(i)) for i in idx.joint_qpos],
        "joint_vel": [(_QVEL, int(i)) for i in idx.joint_dof],
        "task_time_s": [(_TASK, 0)],
    }
    layout = OutputPacket.LAYOUT
    base = float_block(layout)[0]
    rows = []
    for name, values in src.items():
        sub, offset = layout.fields[name][:2]
        if sub.itemsize != 8 * len(values):
            raise ValueError(f"output field {name}: {len(values)} values for {sub}")
        rows += [(s, i, (offset - base) // 8 + k) for k, (s, i) in enumerate(values)]
    rows += [(_UTIME, 0, layout.fields["utime"][1]),
             (_OVERRUNS, 0, layout.fields["overruns"][1]),
             (_STATUS, 0, layout.fields["status"][1])]
    return np.array(rows, dtype=np.int64)


@numba.njit(cache=True, nogil=True)
def _put_uint(out: np.ndarray, offset: int, value: int, size: int) -> None:  # pragma: no cover
    """Write ``value`` as a ``size``-byte little-endian unsigned integer at ``offset``."""
    for k in range(size):
        out[offset + k] = (value >> (8 * k)) & 0xFF


@numba.njit(cache=True, nogil=True)
def _fill_output(qpos: np.ndarray, qvel: np.ndarray, sensordata: np.ndarray,
                 actuator_force: np.ndarray, gear: np.ndarray, table: np.ndarray,
                 floats: np.ndarray, out: np.ndarray, time_s: float, task_time_s: float,
                 overruns: int, status: int, seq: int, ack: int) -> None:  # pragma: no cover
    """The whole output packet (``SimCore.fill_output``): ``table`` rows into ``floats`` (the
    packet's float64 block) and ``out`` (its bytes); the task time only if ``>= 0``."""
    for r in range(table.shape[0]):
        s, i, o = table[r, 0], table[r, 1], table[r, 2]
        if s == _QPOS:
            floats[o] = qpos[i]
        elif s == _QVEL:
            floats[o] = qvel[i]
        elif s == _SENSOR:
            floats[o] = sensordata[i]
        elif s == _TORQUE:
            floats[o] = actuator_force[i] * gear[i]
        elif s == _TASK:
            if task_time_s >= 0.0:
                floats[o] = task_time_s
        elif s == _UTIME:
            _put_uint(out, o, np.int64(np.rint(time_s * 1e6)), 8)
        elif s == _OVERRUNS:
            _put_uint(out, o, overruns & 0xFFFFFFFF, 4)
        else:
            _put_uint(out, o, status, 4)
    out[0] = seq & 0xFF
    out[1] = ack & 0xFF


@numba.njit(cache=True, nogil=True)
def _set_command(torque: np.ndarray, torque_cmd: np.ndarray, gear: np.ndarray,
                 ctrl: np.ndarray) -> bool:  # pragma: no cover
    """``torque_cmd[:] = torque``, ``ctrl[:] = torque / gear``; whether any torque is nonzero."""
    if torque.shape[0] != torque_cmd.shape[0]:
        raise ValueError("a torque command needs one torque per motor")
    nonzero = False
    for k in range(torque_cmd.shape[0]):
        t = torque[k]
        torque_cmd[k] = t
        ctrl[k] = t / gear[k]
        if t != 0.0:
            nonzero = True
    return nonzero


_warmed = False


def _warm_kernels() -> None:
    """Compile (or load from numba's cache) the kernels for the arrays the 2 kHz path passes,
    so the first tick does not."""
    global _warmed
    if _warmed:
        return
    out, inp = OutputPacket(), InputPacket()
    f, g = np.zeros(10), np.ones(10)
    _set_command(inp.torque, f, g, np.zeros(10))  # a received packet's torques
    _set_command(f, f.copy(), g, np.zeros(10))  # an array's
    _fill_output(f, f, f, f, g, np.zeros((0, 3), dtype=np.int64), out.floats,
                 out.bytes_array, 0.0, -1.0, 0, 0, 0, 0)
    _warmed = True


def make_core(terrain: Terrain | None = None, config: SimConfig | None = None) -> SimCore:
    """Convenience: build the model for ``terrain`` and a core standing on its start surface."""
    cfg = config or SimConfig()
    h = cfg.holder
    drops = cfg.drops
    m = build_model(terrain, impratio=cfg.impratio, holder_solref=(h.timeconst_s, h.dampratio),
                    cubes=0 if drops is None else len(drops.after_release_s),
                    cube_size_m=0.15 if drops is None else drops.size_m)
    return SimCore(m, cfg, start_z=terrain.start_z if terrain is not None else 0.0)
