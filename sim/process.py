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

Settings: ``proc.params`` (``PARAMS``: terrain, terrain_seed, drive, camera_render,
publish_footholds) and ``proc.gains_file`` (``hw_config/gains/sim.yaml``: physics, watchdog,
holder, camera, ground-truth rate, lockstep), validated with ``ConfigError`` naming the file
and key.
"""

from __future__ import annotations

import logging
import sys
import time
from collections.abc import Mapping
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from time import perf_counter
from typing import Any, Literal

import yaml

from lcmtypes import depth_frame_t, foothold_set_t, ground_truth_t
from runtime.config import safe_load
from runtime.config_types import ProcessConfig, Profile
from runtime.errors import ConfigError
from runtime.node import HEALTH_FAULT, HEALTH_OK, Context, Inbox, Node
from runtime.pairing import link_token
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
    RELEASE_ON,
    HolderConfig,
    Mode,
    PushConfig,
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
    """Everything the sim process reads from hw_config, validated."""

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


# -- validation helpers ------------------------------------------------------------------------


def _check_keys(file: str, prefix: str, doc: dict[str, Any], allowed: set[str]) -> None:
    for k in doc:
        if k not in allowed:
            raise ConfigError(file, f"{prefix}{k}", "unknown key", ", ".join(sorted(allowed)))


def _num(file: str, key: str, v: Any, *, lo: float | None = None, hi: float | None = None,
         integer: bool = False) -> float:
    if isinstance(v, bool) or not isinstance(v, int if integer else (int, float)):
        raise ConfigError(file, key, f"must be {'an integer' if integer else 'a number'}, "
                                     f"got {v!r}")
    if (lo is not None and v < lo) or (hi is not None and v > hi):
        rng = f"[{'-inf' if lo is None else lo}, {'inf' if hi is None else hi}]"
        raise ConfigError(file, key, f"{v!r} is out of range", allowed=rng)
    return v


def _bool(file: str, key: str, v: Any) -> bool:
    if not isinstance(v, bool):
        raise ConfigError(file, key, f"must be true or false, got {v!r}")
    return v


def _mapping(file: str, key: str, v: Any) -> dict[str, Any]:
    if v is None:
        return {}
    if not isinstance(v, dict):
        raise ConfigError(file, key, f"must be a mapping, got {type(v).__name__}")
    return v


_CAMERA_RANGES: dict[str, tuple[float | None, float | None, bool]] = {
    "width": (1, 4096, True), "height": (1, 4096, True), "fx": (1e-6, None, False),
    "fy": (1e-6, None, False), "cx": (None, None, False), "cy": (None, None, False),
    "decimation": (1, 64, True), "depth_scale": (1e-6, 1.0, False),
    "min_range_m": (0.0, None, False), "max_range_m": (1e-3, 65.0, False),
    "pitch_down_deg": (-90.0, 90.0, False), "rate_hz": (1e-3, 1000.0, False),
    "noise_std_at_1m": (0.0, 1.0, False), "dropout": (0.0, 1.0, False), "seed": (0, None, True),
}


def _render_mode(file: str, key: str, v: Any) -> CameraRender:
    if v not in RENDER_MODES:
        raise ConfigError(file, key, f"unknown value {v!r}", allowed=", ".join(RENDER_MODES))
    return v  # type: ignore[no-any-return]


def _camera(file: str, doc: dict[str, Any]) -> tuple[CameraConfig, bool, CameraRender]:
    allowed = set(_CAMERA_RANGES) | {"enabled", "render", "see_robot", "mount_pos_m"}
    _check_keys(file, "camera.", doc, allowed)
    kw: dict[str, Any] = {}
    for k, (lo, hi, integer) in _CAMERA_RANGES.items():
        if k in doc:
            kw[k] = _num(file, f"camera.{k}", doc[k], lo=lo, hi=hi, integer=integer)
    if "see_robot" in doc:
        kw["see_robot"] = _bool(file, "camera.see_robot", doc["see_robot"])
    if "mount_pos_m" in doc:
        v = doc["mount_pos_m"]
        if not isinstance(v, list) or len(v) != 3:
            raise ConfigError(file, "camera.mount_pos_m", f"must be [x, y, z], got {v!r}")
        kw["mount_pos"] = tuple(_num(file, f"camera.mount_pos_m[{i}]", x) for i, x in enumerate(v))
    cfg = CameraConfig(**kw)
    if cfg.min_range_m >= cfg.max_range_m:
        raise ConfigError(file, "camera.min_range_m", "must be below camera.max_range_m")
    if cfg.out_width < 1 or cfg.out_height < 1:
        raise ConfigError(file, "camera.decimation", "leaves an empty image")
    enabled = _bool(file, "camera.enabled", doc.get("enabled", True))
    render = _render_mode(file, "camera.render", doc.get("render", "auto"))
    return cfg, enabled, render


def load_gains(path: str | Path | None) -> SimSettings:
    """Read ``hw_config/gains/sim.yaml`` (None: all defaults)."""
    if path is None:
        return SimSettings()
    file = str(path)
    try:
        doc = safe_load(Path(path).read_text(encoding="utf-8")) or {}
    except OSError as exc:
        raise ConfigError(file, "gains_file", f"cannot read: {exc.strerror}") from exc
    except yaml.YAMLError as exc:
        raise ConfigError(file, "gains_file", f"not valid YAML: {exc}") from exc
    doc = _mapping(file, "(top level)", doc)
    _check_keys(file, "", doc, {"physics", "watchdog_ms", "holder", "camera", "realtime",
                                "lockstep", "gil_switch_interval_s", "push"})
    phys = _mapping(file, "physics", doc.get("physics"))
    _check_keys(file, "physics.", phys, {"impratio", "pelvis_height_m", "foot_y_m"})
    hold = _mapping(file, "holder", doc.get("holder"))
    _check_keys(file, "holder.", hold, {f.name for f in fields(HolderConfig)})
    hkw: dict[str, Any] = {}
    if "timeconst_s" in hold:
        hkw["timeconst_s"] = _num(file, "holder.timeconst_s", hold["timeconst_s"], lo=0.001,
                                  hi=1.0)
    if "dampratio" in hold:
        hkw["dampratio"] = _num(file, "holder.dampratio", hold["dampratio"], lo=0.1, hi=10.0)
    if "enabled" in hold:
        hkw["enabled"] = _bool(file, "holder.enabled", hold["enabled"])
    if "release_on" in hold:
        if hold["release_on"] not in RELEASE_ON:
            raise ConfigError(file, "holder.release_on", f"unknown value {hold['release_on']!r}",
                              ", ".join(RELEASE_ON))
        hkw["release_on"] = hold["release_on"]
    sim = SimConfig(
        push=_push(file, doc.get("push")),
        watchdog_s=_num(file, "watchdog_ms", doc.get("watchdog_ms", 10.0), lo=0.5, hi=1000.0)
        / 1000.0,
        impratio=_num(file, "physics.impratio", phys.get("impratio", 10.0), lo=1.0, hi=1000.0),
        pelvis_height=_num(file, "physics.pelvis_height_m", phys.get("pelvis_height_m", 0.95),
                           lo=0.7, hi=1.05),
        foot_y=_num(file, "physics.foot_y_m", phys.get("foot_y_m", 0.135), lo=0.0, hi=0.3),
        holder=HolderConfig(**hkw),
    )
    cam, cam_on, render = _camera(file, _mapping(file, "camera", doc.get("camera")))
    lock = _mapping(file, "lockstep", doc.get("lockstep"))
    _check_keys(file, "lockstep.", lock, {"timeout_s", "min_timeout_s", "steps_per_command"})
    rt = _mapping(file, "realtime", doc.get("realtime"))
    _check_keys(file, "realtime.", rt, {"catch_up_ms"})
    timeout_s = _num(file, "lockstep.timeout_s", lock.get("timeout_s", 0.01), lo=1e-3,
                     hi=3600.0)
    gil = doc.get("gil_switch_interval_s", 2e-4)
    if gil is not None:
        gil = _num(file, "gil_switch_interval_s", gil, lo=1e-6, hi=0.1)
    return SimSettings(
        sim=sim, camera=cam, camera_enabled=cam_on, camera_render=render,
        catch_up_s=_num(file, "realtime.catch_up_ms", rt.get("catch_up_ms", 2.0), lo=0.0,
                        hi=100.0) / 1000.0,
        lockstep_timeout_s=timeout_s,
        lockstep_min_timeout_s=_num(file, "lockstep.min_timeout_s",
                                    lock.get("min_timeout_s", min(0.001, timeout_s)),
                                    lo=1e-4, hi=timeout_s),
        steps_per_command=int(_num(file, "lockstep.steps_per_command",
                                   lock.get("steps_per_command", 1), lo=1, hi=100, integer=True)),
        gil_switch_interval_s=gil,
    )


def _push(file: str, v: Any) -> PushConfig | None:
    """``push: {after_release_s, force_n: [x, y, z], duration_s}`` (or null: none)."""
    if v is None:
        return None
    doc = _mapping(file, "push", v)
    _check_keys(file, "push.", doc, {"after_release_s", "force_n", "duration_s"})
    f = doc.get("force_n")
    if not isinstance(f, list) or len(f) != 3:
        raise ConfigError(file, "push.force_n", f"must be [x, y, z] in newtons, got {f!r}")
    if "after_release_s" not in doc:
        raise ConfigError(file, "push.after_release_s", "is required (sim seconds after the "
                          "holder lets go)")
    return PushConfig(
        after_release_s=_num(file, "push.after_release_s", doc["after_release_s"], lo=0.0),
        force_n=tuple(_num(file, f"push.force_n[{i}]", x, lo=-1e4, hi=1e4)  # type: ignore[misc]
                      for i, x in enumerate(f)),
        duration_s=_num(file, "push.duration_s", doc.get("duration_s", 0.1), lo=5e-4, hi=10.0),
    )


#: the keys ``proc.params`` may hold
PARAMS = {
    "terrain": "a terrain YAML file (relative to hw_config) or a generator name",
    "terrain_seed": "seed for a random terrain (stones, blocks)",
    "drive": "auto | periodic | command",
    "camera_render": "auto | process | thread | inline (overrides camera.render) | off (no "
                     "depth camera: nothing renders or publishes DEPTH)",
    "publish_footholds": "also publish the terrain's ground-truth footholds (output role "
                         "'footholds', foothold_set_t) at 30 Hz of sim time",
    "push": "an external force on the pelvis: {after_release_s, force_n: [x, y, z], "
            "duration_s} (overrides the gains file's push)",
    "holder_release": "first_command | first_nonzero_command | manual (overrides the gains "
                      "file's holder.release_on; manual: only the packets' release flag, "
                      "which the torque bridge sets with its params.release_after_s)",
}


def resolve_terrain(proc: ProcessConfig, profile: Profile | None) -> Terrain:
    """``params.terrain``: a YAML file (relative to hw_config) or a generator name;
    ``params.terrain_seed`` overrides the seed of a random terrain."""
    file = str(proc.source_file)
    p = proc.params
    _check_keys(file, proc.key("params") + ".", p, set(PARAMS))
    spec = p.get("terrain", "flat")
    if not isinstance(spec, str):
        raise ConfigError(file, proc.key("params", "terrain"), f"must be a string, got {spec!r}")
    seed = p.get("terrain_seed")
    if seed is not None:
        seed = int(_num(file, proc.key("params", "terrain_seed"), seed, lo=0, integer=True))
    if spec in terrain_mod.GENERATORS:
        kwargs = {} if seed is None else {"seed": seed}
        if seed is not None and spec not in ("stones", "blocks"):
            raise ConfigError(file, proc.key("params", "terrain_seed"),
                              f"terrain {spec!r} is not random", allowed="stones, blocks")
        return terrain_mod.generate(spec, **kwargs)
    if not spec.endswith((".yaml", ".yml")):
        raise ConfigError(file, proc.key("params", "terrain"), f"unknown terrain {spec!r}",
                          allowed=", ".join(terrain_mod.GENERATORS) + " or a .yaml file")
    path = profile.resolve(spec) if profile is not None else Path(spec)
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
            model_args = (settings.terrain, sim.impratio,
                          (sim.holder.timeconst_s, sim.holder.dampratio))
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
        self._gt.num_positions = self.core.m.nq
        self._gt.num_velocities = self.core.m.nv
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
        msg.q = core.d.qpos.tolist()
        msg.v = core.d.qvel.tolist()
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


def make_node(proc: ProcessConfig, profile: Profile) -> Node:
    """Build the sim node for ``proc`` under ``profile`` (mode, hw_config folder)."""
    gains = proc.gains_file
    if gains is not None and not Path(gains).is_absolute():
        gains = profile.resolve(gains)
    settings = load_gains(gains)
    settings = replace(settings, terrain=resolve_terrain(proc, profile))
    file = str(proc.source_file)
    drive = proc.params.get("drive", "auto")
    if drive not in ("auto", "periodic", "command"):
        raise ConfigError(file, proc.key("params", "drive"), f"unknown value {drive!r}",
                          allowed="auto, periodic, command")
    v = proc.params.get("camera_render")
    if v == "off" or v is False:  # (YAML reads a bare off as false) no depth camera: nothing
        # renders or publishes DEPTH -- for profiles without perception
        settings = replace(settings, camera_enabled=False)
    elif v is not None:
        if v not in RENDER_MODES:
            raise ConfigError(file, proc.key("params", "camera_render"), f"unknown value {v!r}",
                              allowed=", ".join((*RENDER_MODES, "off")))
        settings = replace(settings, camera_render=v)
    fh = _bool(file, proc.key("params", "publish_footholds"),
               proc.params.get("publish_footholds", False))
    if "push" in proc.params:  # a push set in the profile (hw_config/push.yaml) wins
        try:
            push = _push(file, proc.params["push"])
        except ConfigError as exc:
            raise ConfigError(file, proc.key("params", exc.key), exc.problem, exc.allowed) from None
        settings = replace(settings, sim=replace(settings.sim, push=push))
    if "holder_release" in proc.params:
        rel = proc.params["holder_release"]
        if rel not in RELEASE_ON:
            raise ConfigError(file, proc.key("params", "holder_release"),
                              f"unknown value {rel!r}", allowed=", ".join(RELEASE_ON))
        settings = replace(settings, sim=replace(
            settings.sim, holder=replace(settings.sim.holder, release_on=rel)))
    rate = proc.rate_hz if proc.rate_hz else 2000.0
    node = SimNode(settings, profile.mode, rate, drive, fh, profile.rtf)
    node.name = proc.name
    return node
