"""The sim process: the target PC as a ``runtime.node.Node`` (UDP state and torques, LCM extras).

Ports: input ``command`` (bytes, the torque packet), outputs ``robot_output`` (bytes, the state
packet), ``ground_truth`` (``ground_truth_t``, 500 Hz by default), ``depth`` (``depth_frame_t``,
30 Hz) and, with ``params.publish_footholds``, ``footholds`` (``foothold_set_t``, ground truth).

Modes (``profile.mode``): ``realtime`` -- periodic at ``rate_hz`` (2 kHz), newest command per
tick, sim-time watchdog, depth rendered in a child process, overruns and the real-time
factor reported; ``lockstep`` -- driven by each command that answers the newest state, with
``trigger_timeout_s`` (timeouts reported, state resent), depth rendered inline, no wall-clock
figures in the packets, so runs are reproducible. ``params.drive: periodic`` makes a lockstep
sim tick on the clock instead (the deterministic harness's sim-time ticks).

Depth rendering: in real time, in a child process (``mj_multiRay`` holds the GIL for ~4 ms
per frame, so a thread would stall this loop); in lockstep, inline at the capture tick.

Settings: ``Params`` (``proc.params``: terrain, terrain_seed, drive, camera_render,
publish_footholds, push, holder_release) and ``Gains`` (``SimGains``, the gains file
``hw_config/gains/sim.yaml``: physics, watchdog, holder, camera, real time, lockstep), read
and checked by ``runtime.params`` (``runtime.builder.build_node``): a ``ConfigError`` names
the file and the key.
"""

from __future__ import annotations

import logging
import sys
import time
from collections.abc import Mapping
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from time import perf_counter
from typing import Literal

from lcmtypes import depth_frame_t, foothold_set_t, ground_truth_t
from runtime.config_types import ProcessConfig, Profile
from runtime.errors import ConfigError
from runtime.node import HEALTH_FAULT, HEALTH_OK, Context, Inbox, Node
from runtime.pairing import link_token
from runtime.params import read, spec
from runtime.udp import ResendTimer
from sim import terrain as terrain_mod
from sim.camera import (
    AsyncDepthRenderer,
    CameraConfig,
    DepthCamera,
    DepthFrame,
    ProcessDepthRenderer,
)
from sim.target_pc import (
    DropsConfig,
    HolderConfig,
    Mode,
    PushConfig,
    ReleaseOn,
    SimConfig,
    TargetPC,
    make_core,
)
from sim.terrain import Terrain

log = logging.getLogger(__name__)

#: how the node is driven: "auto" = periodic in real time, by each command in lockstep;
#: "periodic" in a lockstep profile suits the deterministic harness (sim-time ticks)
Drive = Literal["auto", "periodic", "command"]
CameraRender = Literal["auto", "process", "thread", "inline"]
RENDER_MODES: tuple[str, ...] = ("auto", "process", "thread", "inline")


@dataclass(frozen=True)
class SimSettings:
    """What the sim runs on: its gains file (``settings_of``), the terrain of its params."""

    terrain: Terrain = field(default_factory=terrain_mod.flat)
    sim: SimConfig = field(default_factory=SimConfig)
    camera: CameraConfig = field(default_factory=CameraConfig)
    camera_enabled: bool = True
    camera_render: CameraRender = "auto"  # auto: a child process in real time, inline in lockstep
    lockstep_timeout_s: float = 0.01  # gains/sim.yaml lockstep.timeout_s: the longest wait
    lockstep_min_timeout_s: float = 0.001  # lockstep.min_timeout_s: the shortest (ResendTimer)
    #: real time: after a stall (this VM's, or a busy core) step the physics through up to this
    #: much missed sim time in one tick, so sim time keeps up with the wall clock as a real
    #: robot's would; a longer stall is lost (counted) and the real-time factor shows it
    catch_up_s: float = 0.002
    steps_per_command: int = 1
    gil_switch_interval_s: float | None = 2e-4  # shorter GIL hand-offs (thread renderer only)


# -- the gains file and the params (runtime.params) -------------------------------------------


@dataclass(frozen=True)
class PhysicsGains:
    """``physics:``: MuJoCo's contact model and the standing pose of the start."""

    impratio: float = spec(SimConfig.impratio, lo=1.0, hi=1000.0)
    pelvis_height_m: float = spec(SimConfig.pelvis_height, lo=0.7, hi=1.05, unit="m")
    foot_y_m: float = spec(SimConfig.foot_y, lo=0.0, hi=0.3, unit="m")


_CAM = CameraConfig  # the camera's defaults are its own


@dataclass(frozen=True)
class CameraGains:
    """``camera:``: the depth camera (``sim.camera.CameraConfig``), whether it is on and how
    it renders."""

    enabled: bool = True
    #: auto: a child process in real time, inline in lockstep
    render: str = spec("auto", choices=RENDER_MODES)
    width: int = spec(_CAM.width, lo=1, hi=4096)  # full-resolution intrinsics
    height: int = spec(_CAM.height, lo=1, hi=4096)
    fx: float = spec(_CAM.fx, lo=1e-6)
    fy: float = spec(_CAM.fy, lo=1e-6)
    cx: float = spec(_CAM.cx)
    cy: float = spec(_CAM.cy)
    decimation: int = spec(_CAM.decimation, lo=1, hi=64)
    depth_scale: float = spec(_CAM.depth_scale, lo=1e-6, hi=1.0, unit="m")
    min_range_m: float = spec(_CAM.min_range_m, lo=0.0, unit="m")
    max_range_m: float = spec(_CAM.max_range_m, lo=1e-3, hi=65.0, unit="m")
    rate_hz: float = spec(_CAM.rate_hz, lo=1e-3, hi=1000.0, unit="Hz")
    noise_std_at_1m: float = spec(_CAM.noise_std_at_1m, lo=0.0, hi=1.0, unit="m")
    dropout: float = spec(_CAM.dropout, lo=0.0, hi=1.0)
    see_robot: bool = _CAM.see_robot
    seed: int = spec(_CAM.seed, lo=0)

    def __post_init__(self) -> None:
        if self.min_range_m >= self.max_range_m:
            raise ConfigError("<CameraGains>", "min_range_m", f"{self.min_range_m} is not below "
                              f"max_range_m ({self.max_range_m})",
                              f"[0.0, {self.max_range_m}) m")
        if self.width // self.decimation < 1 or self.height // self.decimation < 1:
            raise ConfigError("<CameraGains>", "decimation", f"{self.decimation} leaves an "
                              f"empty image of {self.width} x {self.height}",
                              f"[1, {min(self.width, self.height)}]")

    def config(self) -> CameraConfig:
        """The camera's own settings; its mount on the pelvis is the robot's
        (``runtime.robot``, CameraConfig's default), not a gain."""
        mount = ("mount_pos", "pitch_down_deg")
        return CameraConfig(**{f.name: getattr(self, f.name) for f in fields(CameraConfig)
                               if f.name not in mount})


@dataclass(frozen=True)
class RealtimeGains:
    """``realtime:``."""

    #: after a stall, step through up to this much missed sim time at once
    catch_up_ms: float = spec(2.0, lo=0.0, hi=100.0, unit="ms")


@dataclass(frozen=True)
class LockstepGains:
    """``lockstep:``: the resend timeout's range (``runtime.udp.ResendTimer``)."""

    timeout_s: float = spec(0.01, lo=1e-3, hi=3600.0, unit="s")  # the longest wait
    min_timeout_s: float = spec(0.001, lo=1e-4, hi=3600.0, unit="s")  # the shortest
    steps_per_command: int = spec(1, lo=1, hi=100)

    def __post_init__(self) -> None:
        if self.min_timeout_s > self.timeout_s:
            raise ConfigError("<LockstepGains>", "min_timeout_s", f"{self.min_timeout_s} is "
                              f"above timeout_s ({self.timeout_s})",
                              f"[0.0001, {self.timeout_s}] s")


@dataclass(frozen=True)
class SimGains:
    """``hw_config/gains/sim.yaml`` (the process module's ``Gains``): physics, watchdog,
    holder, camera, real time, lockstep; every key optional."""

    physics: PhysicsGains = spec(default_factory=PhysicsGains)
    #: torques drop to zero this long (sim time) after the last command
    watchdog_ms: float = spec(10.0, lo=0.5, hi=1000.0, unit="ms")
    holder: HolderConfig = spec(default_factory=HolderConfig)
    camera: CameraGains = spec(default_factory=CameraGains)
    realtime: RealtimeGains = spec(default_factory=RealtimeGains)
    lockstep: LockstepGains = spec(default_factory=LockstepGains)
    #: shorter GIL hand-offs, for camera.render: thread only (None: Python's own)
    gil_switch_interval_s: float | None = spec(2e-4, lo=1e-6, hi=0.1, unit="s")
    push: PushConfig | None = None  # an external force on the pelvis


def settings_of(gains: SimGains, terrain: Terrain | None = None) -> SimSettings:
    """What the sim runs on, from its gains file (and the terrain of its params)."""
    phys, lock = gains.physics, gains.lockstep
    sim = SimConfig(push=gains.push, watchdog_s=gains.watchdog_ms / 1000.0,
                    impratio=phys.impratio, pelvis_height=phys.pelvis_height_m,
                    foot_y=phys.foot_y_m, holder=gains.holder)
    return SimSettings(
        terrain=terrain if terrain is not None else terrain_mod.flat(),
        sim=sim, camera=gains.camera.config(), camera_enabled=gains.camera.enabled,
        camera_render=gains.camera.render,  # type: ignore[arg-type]
        catch_up_s=gains.realtime.catch_up_ms / 1000.0,
        lockstep_timeout_s=lock.timeout_s, lockstep_min_timeout_s=lock.min_timeout_s,
        steps_per_command=lock.steps_per_command,
        gil_switch_interval_s=gains.gil_switch_interval_s,
    )


#: ``params.camera_render`` may also be ``off`` (YAML reads a bare off as false)
CameraRenderParam = Literal["auto", "process", "thread", "inline", "off", False]


@dataclass(frozen=True)
class Params:
    """The sim's ``params:`` (processes.yaml, a profile's ``overrides:``)."""

    #: a variant of the gains file (its ``variants:``), e.g. depth_noise; none: the top level
    variant: str | None = None
    #: a terrain YAML file (relative to hw_config) or a generator name
    terrain: str = "flat"
    #: seed for a random terrain (stones, blocks)
    terrain_seed: int | None = spec(None, lo=0)
    #: auto: periodic in real time, by each command in lockstep
    drive: Drive = "auto"
    #: overrides camera.render; off: no depth camera (nothing renders or publishes DEPTH)
    camera_render: CameraRenderParam | None = spec(None, choices=(*RENDER_MODES, "off"))
    #: also publish the terrain's ground-truth footholds (output role 'footholds',
    #: foothold_set_t) at 30 Hz of sim time
    publish_footholds: bool = False
    #: an external force on the pelvis (overrides the gains file's push)
    push: PushConfig | None = None
    #: foam cubes dropped in front of the robot (moving obstacles, Table IV)
    drops: DropsConfig | None = None
    #: overrides the gains file's holder.release_on; manual: only the packets' release flag,
    #: which the torque bridge sets with its params.release_after_s
    holder_release: ReleaseOn | None = None


#: the gains file (``gains:``, hw_config/gains/sim.yaml), section by section
Gains = SimGains


def resolve_terrain(proc: ProcessConfig, profile: Profile | None,
                    params: Params | None = None) -> Terrain:
    """``params.terrain``: a YAML file (relative to hw_config) or a generator name;
    ``params.terrain_seed`` overrides the seed of a random terrain. ``params``: ``proc``'s
    as read by the builder (None: read here)."""
    file = str(proc.source_file)
    if params is None:
        params = read(Params, proc.params, file, key=proc.key("params"))
    name, seed = params.terrain, params.terrain_seed
    if name in terrain_mod.GENERATORS:
        kwargs = {} if seed is None else {"seed": seed}
        if seed is not None and name not in ("stones", "blocks"):
            raise ConfigError(file, proc.key("params", "terrain_seed"),
                              f"terrain {name!r} is not random", allowed="stones, blocks")
        return terrain_mod.generate(name, **kwargs)
    if not name.endswith((".yaml", ".yml")):
        raise ConfigError(file, proc.key("params", "terrain"), f"unknown terrain {name!r}",
                          allowed=", ".join(terrain_mod.GENERATORS) + " or a .yaml file")
    path = profile.resolve(name) if profile is not None else Path(name)
    t = terrain_mod.load_terrain(path)
    if seed is not None:
        if t.seed is None:
            raise ConfigError(file, proc.key("params", "terrain_seed"),
                              f"terrain {t.name!r} from {path} is not random")
        args = {k: v for k, v in t.params.items() if k != "samples"}
        args["seed"] = seed
        t = terrain_mod.generate(t.name, **args)
    return t


RENDER_STARTUP_S = 30.0  # how long setup waits for the depth render process to boot
FALL_HEIGHT_M = 0.6  # a fall: the pelvis less than this over the ground under it
JUDGE_PERIOD_US = 20_000  # the robot's truth (fall, distance) checked at 50 Hz of sim time
FOOTHOLD_PERIOD_US = 33_333  # ground-truth footholds at the rate S3 would publish them

# -- the node ----------------------------------------------------------------------------------


class SimNode(Node):
    """The MuJoCo target PC: steps physics, answers torque packets, publishes state and depth."""

    name = "sim"
    inputs: Mapping[str, type] = {"command": bytes}
    outputs: Mapping[str, type] = {
        "robot_output": bytes, "ground_truth": ground_truth_t, "depth": depth_frame_t,
    }

    def __init__(self, settings: SimSettings, mode: Mode, rate_hz: float = 2000.0,
                 drive: Drive = "auto", publish_footholds: bool = False,
                 rtf: float = 1.0) -> None:
        self.settings = settings
        self._footholds: foothold_set_t | None = None
        if publish_footholds:  # an extra output role, bound in hw_config like the others
            self.outputs = {**type(self).outputs, "footholds": foothold_set_t}
            self._footholds = terrain_mod.foothold_set_msg(settings.terrain)
        self._next_fh_us = 0
        self.mode = mode
        self.period_s = 1.0 / rate_hz
        if drive == "auto":
            drive = "command" if mode == "lockstep" else "periodic"
        self.drive = drive
        #: wall-clock figures (task time, overruns, real-time factor) only in real time: in
        #: lockstep they would make two runs differ
        self.wall_clock = mode == "realtime"
        if drive == "command":
            self.trigger_role = "command"
            self.trigger_policy = "newest"
            #: the resend timeout follows the measured round trips (ResendTimer): the runner
            #: reads ``trigger_timeout_s`` before each wait
            self.resend = ResendTimer(settings.lockstep_min_timeout_s,
                                      settings.lockstep_timeout_s)
            self.trigger_timeout_s: float | None = self.resend.timeout_s
        else:
            self.trigger_role = None
            self.trigger_timeout_s = None
            # periodic: every torque packet that came since the last tick is read, in order
            # (counted, the newest applied), as the target PC reads its socket
            self.input_policy = {"command": "each"}
        render = settings.camera_render
        if render == "auto":  # inline in lockstep: frames are deterministic
            render = "process" if self.wall_clock else "inline"
        self.render_mode = render if settings.camera_enabled else "off"
        renderer = None
        if self.render_mode == "process":  # first, so the child boots while this one does
            sim = settings.sim
            drops = sim.drops
            model_args = (settings.terrain, sim.impratio,
                          (sim.holder.timeconst_s, sim.holder.dampratio),
                          0 if drops is None else len(drops.after_release_s),
                          0.15 if drops is None else drops.size_m)
            renderer = ProcessDepthRenderer(model_args, settings.camera)
        self.core = make_core(settings.terrain, settings.sim)
        self.tpc = TargetPC(self.core, mode, settings.steps_per_command, link_token())
        # periodic: as many physics steps per tick as fit the period (1 at 2 kHz)
        ratio = self.period_s / self.core.dt
        self.steps_per_tick = max(1, round(ratio))
        self.tpc.stats.target_rtf = rtf
        if drive == "periodic":
            self.tpc.stats.period_s = self.period_s
            if abs(ratio - self.steps_per_tick) > 1e-6:
                log.warning("sim period %.6f s is not a multiple of the physics step %.6f s: "
                            "sim time runs at %.3fx the tick clock", self.period_s,
                            self.core.dt, self.steps_per_tick / ratio)
        self._max_catch_up = round(settings.catch_up_s / self.core.dt)
        self.catch_up_steps = 0  # physics steps taken to make up for missed slots
        self.lost_slots = 0  # missed slots beyond catch_up_ms: sim time lost to the wall clock
        self._next_judge_us = 0
        self.fell_at: float | None = None
        self._x_release: float | None = None
        self._walked_m = 0.0
        self._pelvis_z = 0.0
        self._gt = ground_truth_t()
        self._gt.num_positions = self.core.nq_robot
        self._gt.num_velocities = self.core.nv_robot
        self._camera: DepthCamera | None = None
        self.renderer: AsyncDepthRenderer | ProcessDepthRenderer | None = None
        self._next_depth_us = 0
        self._depth_every_us = round(1e6 / settings.camera.rate_hz)
        self.depth_published = 0
        self._prev_utime: int | None = None
        self._period_us = round(self.period_s * 1e6)
        self._old_switch: float | None = None
        self._depth_dropped = 0
        if settings.camera_enabled:
            self._camera = DepthCamera(self.core.m, settings.camera)
            if render == "thread":
                self.renderer = AsyncDepthRenderer(self._camera)
            elif render == "process":
                self.renderer = renderer

    def setup(self, ctx: Context) -> None:
        if isinstance(self.renderer, ProcessDepthRenderer):
            # let the render process finish booting (imports, model) before the 2 kHz loop
            # starts, so the two do not fight over the cores during the first second
            t0 = time.monotonic()
            if self.renderer.wait_ready(RENDER_STARTUP_S):
                log.info("depth render process ready after %.1f s", time.monotonic() - t0)
            else:
                log.warning("depth render process not ready after %.0f s: starting without it "
                            "(frames follow if it comes up)", RENDER_STARTUP_S)
        if self.render_mode == "thread" and self.settings.gil_switch_interval_s is not None:
            self._old_switch = sys.getswitchinterval()
            sys.setswitchinterval(self.settings.gil_switch_interval_s)
        # the first state goes out before any command: in lockstep it is what gets answered
        ctx.publish("robot_output", bytes(self.tpc.encode_state()))
        if self.trigger_role is not None:
            self.resend.sent(perf_counter())
        self._publish_extras(ctx, self.core.utime)

    def tick(self, ctx: Context, inbox: Inbox) -> None:
        t0 = perf_counter()
        tpc, core = self.tpc, self.core
        skipped = 0
        if self.trigger_role is None:
            if inbox.is_fresh("command"):  # nothing came: nothing to pop
                while (data := inbox.pop("command")) is not None:
                    tpc.take(data)
            now = ctx.now_utime  # the scheduled time: a jump of several periods = skipped slots
            prev = self._prev_utime
            self._prev_utime = now
            steps = self.steps_per_tick
            if prev is not None and self._period_us > 0:
                skipped = max(0, (now - prev) // self._period_us - 1)
                if skipped and self.wall_clock:
                    # the loop missed slots (a stall): step through them with the same torque,
                    # as the real robot's physics would have gone on; beyond the cap they are
                    # lost
                    extra = min(skipped, self._max_catch_up)
                    self.catch_up_steps += extra * steps
                    self.lost_slots += skipped - extra
                    steps += extra * steps
            out = tpc.realtime_cycle(None, steps)
            t = core.d.time
            utime = round(t * 1e6)  # core.utime
        else:
            data = inbox.trigger()
            out = tpc.lockstep_cycle(data)
            if data is None:
                self.resend.expired()  # the same state goes again: wait longer for it
            elif out is not None:
                self.resend.answered(t0)
            # driven by raw command bytes, which carry no sim time: the sim is the clock, so
            # its outputs (and their decimation) run on physics time
            t = core.d.time
            utime = ctx.now_utime = round(t * 1e6)
        if out is not None:
            # the packet's own buffer (``out`` views it): the live runner sends it at once and
            # the harness copies it, so no copy is made here
            ctx.publish("robot_output", tpc.out.buffer)
            if self.trigger_role is not None:
                if data is not None:  # a new state, not a resend
                    self.resend.sent(perf_counter())
                self.trigger_timeout_s = self.resend.timeout_s
        core.prepare()  # the next step's first half, once the state is on its way
        self._publish_extras(ctx, utime)
        if utime >= self._next_judge_us:
            self._next_judge_us = utime + JUDGE_PERIOD_US
            self._judge()
        if self.wall_clock:
            end = perf_counter()  # CLOCK_MONOTONIC, as time.monotonic
            tpc.stats.record(end - t0, t, skipped, end)

    def _judge(self) -> None:
        """The truth about the robot, for status and health: distance walked since the holder
        let go, and whether it fell (pelvis less than FALL_HEIGHT_M over the ground under it,
        the rule ``cassie experiment`` judges by)."""
        q = self.core.d.qpos
        x, y, z = float(q[0]), float(q[1]), float(q[2])
        self._pelvis_z = z - self.settings.terrain.height_at(x, y)
        if self.core.release_time is not None:
            if self._x_release is None:
                self._x_release = x
            self._walked_m = x - self._x_release
            if self.fell_at is None and self._pelvis_z < FALL_HEIGHT_M:
                self.fell_at = self.core.time
                log.warning("the robot fell at t=%.3f s: pelvis %.2f m over the ground",
                            self.core.time, self._pelvis_z)

    def _publish_extras(self, ctx: Context, now: int) -> None:
        """Ground truth, footholds and depth frames, when due at sim time ``now`` (us)."""
        core = self.core
        if self._footholds is not None and now >= self._next_fh_us:
            self._next_fh_us = now + FOOTHOLD_PERIOD_US
            self._footholds.header.utime = now
            ctx.publish("footholds", self._footholds)
        if ctx.due("ground_truth"):  # decimated by processes.sim.output_rate_hz
            ctx.publish("ground_truth", self._ground_truth())
        if self._camera is None:
            return
        if self.renderer is not None:
            frame = self.renderer.poll()
            if frame is not None:
                ctx.publish("depth", self._depth_msg(frame))
            if now >= self._next_depth_us:
                self._next_depth_us += self._depth_every_us
                if self._next_depth_us <= now:  # fell far behind: realign to the clock
                    self._next_depth_us = now + self._depth_every_us
                self.renderer.request(core.d.qpos, now)
        elif now >= self._next_depth_us:
            self._next_depth_us += self._depth_every_us
            t0 = time.perf_counter()
            f = self._camera.render(core.d.qpos, now)
            f.render_s = time.perf_counter() - t0
            ctx.publish("depth", self._depth_msg(f))

    def _ground_truth(self) -> ground_truth_t:
        core = self.core
        msg = self._gt
        msg.header.utime = core.utime
        msg.q = core.d.qpos[:core.nq_robot].tolist()  # the robot's (not the cubes')
        msg.v = core.d.qvel[:core.nv_robot].tolist()
        com, vel = core.com_and_velocity()
        msg.com = com.tolist()
        msg.com_vel = vel.tolist()
        msg.foot_contact = list(core.foot_contacts())
        msg.foot_pos = [core.d.geom_xpos[g].tolist() for g in core.idx.foot_geoms]
        return msg

    def _depth_msg(self, f: DepthFrame) -> depth_frame_t:
        cam = self.settings.camera
        fx, fy, cx, cy = cam.decimated_intrinsics()
        msg = depth_frame_t()
        msg.header.utime = f.utime
        msg.height, msg.width = f.depth.shape
        msg.fx, msg.fy, msg.cx, msg.cy = fx, fy, cx, cy
        msg.depth_scale = cam.depth_scale
        msg.camera_pos = f.pos.tolist()
        msg.camera_quat = f.quat.tolist()
        data = f.depth.astype("<u2", copy=False).tobytes()
        msg.num_bytes = len(data)
        msg.data = data
        self.depth_published += 1
        return msg

    def release_holder(self) -> None:
        self.core.release_holder()

    def close(self) -> None:
        if self.renderer is not None:
            self._depth_dropped = self.renderer.dropped
            self.renderer.close()
            self.renderer = None
        if self._old_switch is not None:
            sys.setswitchinterval(self._old_switch)
            self._old_switch = None

    def health(self) -> int:
        """A fault once the robot has fell: the launch that ran it did not succeed."""
        return HEALTH_FAULT if self.fell_at is not None else HEALTH_OK

    def counters(self) -> dict[str, float]:
        """Steps, packets and the robot's truth, for reports (e.g. a torque per step)."""
        tpc, c = self.tpc, self.core
        return {
            "sim_time_s": c.time,
            "steps": c.steps,
            # datagrams: new states and lockstep resends (a resend keeps its seq)
            "packets_sent": tpc.link.sent + tpc.timeouts,
            "packets_resent": tpc.timeouts,
            "commands_received": tpc.link.received,
            "commands_lost": tpc.link.lost,
            "commands_malformed": tpc.link.malformed,
            "commands_foreign": tpc.link.foreign,  # another launch's pairing token
            "zero_torque_steps": c.zero_torque_steps,
            # lockstep: the chain's smoothed round trip and the resend timeout it sets (0 when
            # the sim runs on its own clock)
            "round_trip_ms": (1e3 * self.resend.srtt if self.trigger_role is not None
                              and self.resend.samples else 0.0),
            "resend_timeout_ms": (1e3 * self.resend.timeout_s if self.trigger_role is not None
                                  else 0.0),
            "rtf": tpc.stats.rtf if self.wall_clock else 0.0,
            "overruns": tpc.stats.overruns,
            "catch_up_steps": self.catch_up_steps,
            "lost_slots": self.lost_slots,
            "holder": float(c.holder_engaged),
            "walked_m": self._walked_m,
            "pelvis_height_m": self._pelvis_z,
            "fell": float(self.fell_at is not None),
            "depth_frames": self.depth_published,
        }

    def robot_status(self) -> str:
        """What the robot does, from the sim's truth: held, walking (distance), or fallen."""
        c = self.core
        if self.fell_at is not None:
            return (f"FELL at t={self.fell_at:.2f} s after {self._walked_m:.2f} m (pelvis "
                    f"{self._pelvis_z:.2f} m over the ground)")
        if c.release_time is None:
            return "held by the start-up holder"
        t = c.time - c.release_time
        v = self._walked_m / t if t > 0 else 0.0
        return (f"walked {self._walked_m:.2f} m in {t:.1f} s ({v:.2f} m/s), pelvis "
                f"{self._pelvis_z:.2f} m")

    def status(self) -> str:
        """One line: the robot's truth, then mode, sim time, real-time factor, overruns, link
        counts, holder, watchdog, lockstep timeouts, depth frames."""
        s = self.robot_status() + " | " + self.tpc.summary()
        if self.render_mode != "off":
            dropped = self.renderer.dropped if self.renderer is not None else self._depth_dropped
            s += f" depth={self.depth_published} ({self.render_mode}, dropped {dropped})"
        return s


def make_node(proc: ProcessConfig, profile: Profile, params: Params, gains: SimGains) -> Node:
    """The sim node for ``proc`` under ``profile`` (mode, hw_config folder), of ``gains`` and
    ``params`` (``runtime.builder.build_node`` reads and checks both)."""
    settings = settings_of(gains, resolve_terrain(proc, profile, params))
    if params.camera_render in ("off", False):  # no depth camera: nothing renders or
        # publishes DEPTH -- for profiles without perception
        settings = replace(settings, camera_enabled=False)
    elif params.camera_render is not None:
        settings = replace(settings, camera_render=params.camera_render)
    if params.push is not None:  # a push set in the profile (hw_config/push.yaml) wins
        settings = replace(settings, sim=replace(settings.sim, push=params.push))
    if params.drops is not None:
        settings = replace(settings, sim=replace(settings.sim, drops=params.drops))
    if params.holder_release is not None:
        settings = replace(settings, sim=replace(
            settings.sim, holder=replace(settings.sim.holder, release_on=params.holder_release)))
    rate = proc.rate_hz if proc.rate_hz else 2000.0
    node = SimNode(settings, profile.mode, rate, params.drive, params.publish_footholds,
                   profile.rtf)
    node.name = proc.name
    return node
