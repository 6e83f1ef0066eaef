"""A simulated RealSense D455 on Cassie's pelvis, rendered by ray casting (no OpenGL).

Each decimated pixel is one ray cast with ``mujoco.mj_multiRay`` from the optical centre
through the pixel; the ray length times the ray's z component gives the z16 depth the real
camera reports (0 = no data). The directions, hit buffers and the output image are allocated
once.

``mj_multiRay`` holds Python's GIL for the whole call (about 4 ms for 106 x 60 rays), so a
renderer *thread* would stall the 2 kHz loop of its own process for that long. The live sim
therefore renders in a child process (``ProcessDepthRenderer``: its own model and ``MjData``,
qpos in and the z16 image out over a pipe); ``AsyncDepthRenderer`` (a thread) remains for
callers without a real-time loop, and lockstep renders inline.
"""

from __future__ import annotations

import logging
import os
import struct
import threading
import time
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np

from runtime.robot import CAMERA_MOUNT_POS_M, CAMERA_PITCH_DOWN_DEG, mount_rotation

PELVIS_BODY = "cassie-pelvis"
log = logging.getLogger(__name__)


@dataclass(frozen=True)
class CameraConfig:
    """Intrinsics (full resolution), decimation, range, mount on the pelvis, noise, rate."""

    width: int = 848
    height: int = 480
    fx: float = 426.0
    fy: float = 426.0
    cx: float = 424.0
    cy: float = 240.0
    decimation: int = 8  # the RealSense decimation filter: 848 x 480 -> 106 x 60
    depth_scale: float = 0.001  # metres per z16 unit
    min_range_m: float = 0.4
    max_range_m: float = 6.0
    mount_pos: tuple[float, float, float] = CAMERA_MOUNT_POS_M  # pelvis frame (runtime.robot)
    pitch_down_deg: float = CAMERA_PITCH_DOWN_DEG  # optical axis below the pelvis x axis
    rate_hz: float = 30.0
    noise_std_at_1m: float = 0.0  # depth noise std (m) at 1 m; grows with depth squared
    dropout: float = 0.0  # fraction of pixels randomly set to 0 (no data)
    see_robot: bool = True  # the legs show up in the image, as on the robot
    seed: int = 0

    @property
    def out_width(self) -> int:
        return self.width // self.decimation

    @property
    def out_height(self) -> int:
        return self.height // self.decimation

    def decimated_intrinsics(self) -> tuple[float, float, float, float]:
        """(fx, fy, cx, cy) of the decimated image (pixel centres preserved)."""
        k = self.decimation
        return (self.fx / k, self.fy / k, (self.cx + 0.5) / k - 0.5, (self.cy + 0.5) / k - 0.5)


@dataclass
class DepthFrame:
    """One rendered frame: z16 image (height, width), sim time and camera pose at capture."""

    utime: int
    depth: np.ndarray  # uint16 (h, w)
    pos: np.ndarray  # (3,) optical centre, world
    quat: np.ndarray  # (4,) w x y z, world <- optical
    render_s: float = 0.0


class DepthCamera:
    """Ray-cast depth renderer; owns an ``MjData`` so it can run beside the physics."""

    def __init__(self, m: mujoco.MjModel, cfg: CameraConfig) -> None:
        self.m = m
        self.cfg = cfg
        self.d = mujoco.MjData(m)
        self.body = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, PELVIS_BODY)
        w, h = cfg.out_width, cfg.out_height
        fx, fy, cx, cy = cfg.decimated_intrinsics()
        u, v = np.meshgrid(np.arange(w, dtype=float), np.arange(h, dtype=float))
        rays = np.stack([(u - cx) / fx, (v - cy) / fy, np.ones_like(u)], axis=-1).reshape(-1, 3)
        norm = np.linalg.norm(rays, axis=1)
        self.dirs_cam = rays / norm[:, None]  # unit rays, optical frame
        self.z_of_unit = 1.0 / norm  # depth (z) per metre along the ray
        self.n = w * h
        self.r_pc = mount_rotation(cfg.pitch_down_deg)
        self.mount = np.asarray(cfg.mount_pos, dtype=float)
        groups = [1, 1, 1 if cfg.see_robot else 0, 0, 0, 0]
        self.geomgroup = np.array(groups, dtype=np.uint8)
        self.vec = np.zeros((self.n, 3))
        self.vec_flat = self.vec.reshape(-1)
        self.dist = np.zeros(self.n)
        self.geomid = np.zeros(self.n, dtype=np.int32)
        self.depth_m = np.zeros(self.n)
        self.image = np.zeros((h, w), dtype=np.uint16)
        self.pnt = np.zeros(3)
        self.r_wc = np.zeros((3, 3))
        self.quat = np.zeros(4)
        self.rng = np.random.default_rng(cfg.seed)

    def render(self, qpos: np.ndarray, utime: int = 0) -> DepthFrame:
        """Render the view from robot configuration ``qpos``; reuses this camera's buffers
        (the returned frame's arrays are overwritten by the next call)."""
        cfg = self.cfg
        d = self.d
        d.qpos[:] = qpos
        mujoco.mj_kinematics(self.m, d)
        r_wp = d.xmat[self.body].reshape(3, 3)
        np.matmul(r_wp, self.mount, out=self.pnt)
        self.pnt += d.xpos[self.body]
        np.matmul(r_wp, self.r_pc, out=self.r_wc)
        np.matmul(self.dirs_cam, self.r_wc.T, out=self.vec)
        mujoco.mj_multiRay(self.m, d, self.pnt, self.vec_flat, self.geomgroup, 1, self.body,
                           self.geomid, self.dist, None, self.n, cfg.max_range_m)
        z = self.depth_m
        np.multiply(self.dist, self.z_of_unit, out=z)
        if cfg.noise_std_at_1m > 0.0:
            z += self.rng.standard_normal(self.n) * (cfg.noise_std_at_1m * z * z)
        bad = (self.geomid < 0) | (z < cfg.min_range_m) | (z > cfg.max_range_m)
        if cfg.dropout > 0.0:
            bad |= self.rng.random(self.n) < cfg.dropout
        z[bad] = 0.0
        np.rint(z / cfg.depth_scale, out=z)
        np.clip(z, 0, 65535, out=z)
        self.image.reshape(-1)[:] = z
        mujoco.mju_mat2Quat(self.quat, self.r_wc.reshape(-1))
        return DepthFrame(utime=utime, depth=self.image, pos=self.pnt, quat=self.quat)


class AsyncDepthRenderer:
    """Renders frames in a background thread; ``request`` never blocks the caller.

    The caller hands over a copy of ``qpos`` with its sim time; when the thread is still busy
    with the previous frame the request is dropped and counted. ``poll`` returns a finished
    frame (its own copy) once, then None until the next one.
    """

    def __init__(self, camera: DepthCamera) -> None:
        self.camera = camera
        self._qpos = np.zeros(camera.m.nq)
        self._utime = 0
        self._cv = threading.Condition()
        self._pending = False
        self._busy = False
        self._done: DepthFrame | None = None
        self._stop = False
        self.dropped = 0
        self.rendered = 0
        self.last_render_s = 0.0
        self._thread = threading.Thread(target=self._run, name="depth-render", daemon=True)
        self._thread.start()

    def request(self, qpos: np.ndarray, utime: int) -> bool:
        """Ask for a frame of ``qpos`` at ``utime``; False (and counted) if still busy."""
        with self._cv:
            if self._pending or self._busy:
                self.dropped += 1
                return False
            self._qpos[:] = qpos
            self._utime = utime
            self._pending = True
            self._cv.notify()
        return True

    def poll(self) -> DepthFrame | None:
        """The newest finished frame, once; None if none finished since the last poll."""
        with self._cv:
            frame, self._done = self._done, None
        return frame

    def _run(self) -> None:
        while True:
            with self._cv:
                while not self._pending and not self._stop:
                    self._cv.wait()
                if self._stop:
                    return
                self._pending = False
                self._busy = True
                utime = self._utime
            t0 = time.perf_counter()
            f = self.camera.render(self._qpos, utime)
            frame = DepthFrame(utime, f.depth.copy(), f.pos.copy(), f.quat.copy(),
                               time.perf_counter() - t0)
            with self._cv:
                self._done = frame
                self._busy = False
                self.rendered += 1
                self.last_render_s = frame.render_s

    def close(self) -> None:
        """Stop the thread (waits for the frame in progress)."""
        with self._cv:
            self._stop = True
            self._cv.notify()
        self._thread.join(timeout=2.0)


_REQ = struct.Struct("<q")  # utime, then nq float64 of qpos
_REP = struct.Struct("<qd3d4d")  # utime, render seconds, camera pos, camera quat; then image
_LEN = struct.Struct("<I")  # every message on the pipes is length-prefixed


def _read_exact(stream: Any, n: int) -> bytes:
    data = stream.read(n)
    if data is None or len(data) != n:
        raise EOFError
    return bytes(data)


def _serve() -> int:
    """Child process (``python -m sim.camera``): read the model arguments and camera settings
    (a pickle), build the same model, then answer each qpos with a rendered frame."""
    import pickle
    import signal
    import sys

    from sim.model import build_model

    # Ctrl-C and the supervisor's SIGINT go to the whole process group: the parent stops this
    # child by closing the pipe (EOF), so that a stop never prints a traceback from here
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    rd = sys.stdin.buffer
    wr = os.fdopen(os.dup(1), "wb", buffering=0)  # the protocol owns the original stdout;
    os.dup2(2, 1)  # anything else printed goes to stderr
    try:
        (n,) = _LEN.unpack(_read_exact(rd, _LEN.size))
        model_args, cfg = pickle.loads(_read_exact(rd, n))
        cam = DepthCamera(build_model(*model_args), cfg)
        nq = cam.m.nq
        wr.write(_LEN.pack(5) + b"ready")
        while True:
            (n,) = _LEN.unpack(_read_exact(rd, _LEN.size))
            if n == 0:
                return 0
            msg = _read_exact(rd, n)
            (utime,) = _REQ.unpack_from(msg, 0)
            qpos = np.frombuffer(msg, "<f8", nq, _REQ.size)
            t0 = time.perf_counter()
            f = cam.render(qpos, utime)
            dt = time.perf_counter() - t0
            body = _REP.pack(utime, dt, *f.pos, *f.quat) + f.depth.astype("<u2").tobytes()
            wr.write(_LEN.pack(len(body)) + body)
    except (EOFError, BrokenPipeError):
        return 0


class ProcessDepthRenderer:
    """Renders frames in a child process, so ray casting never holds this process's GIL.

    Same interface as ``AsyncDepthRenderer``: ``request`` writes qpos (about 300 bytes) to the
    child and returns at once, False (counted as dropped) while a frame is still in progress;
    ``poll`` returns the finished frame once. The child (``python -m sim.camera``) builds the
    model from the same arguments as the parent (terrain, impratio, holder solref), so the qpos
    layouts match.
    """

    def __init__(self, model_args: tuple[Any, ...], cfg: CameraConfig) -> None:
        import pickle
        import subprocess
        import sys

        env = dict(os.environ)  # make `sim` importable from wherever the parent runs
        root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
        env["PYTHONPATH"] = os.pathsep.join(p for p in (root, env.get("PYTHONPATH")) if p)
        self._proc = subprocess.Popen(
            [sys.executable, "-m", "sim.camera"], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
            bufsize=0, env=env,
        )
        assert self._proc.stdin is not None and self._proc.stdout is not None
        self._out_fd = self._proc.stdin.fileno()
        self._in_fd = self._proc.stdout.fileno()
        os.set_blocking(self._in_fd, False)
        init = pickle.dumps((model_args, cfg))
        self._write(_LEN.pack(len(init)) + init)
        self.cfg = cfg
        self._req = bytearray()  # sized at the first request, then reused
        self._req_q = np.zeros(0)
        self._shape = (cfg.out_height, cfg.out_width)
        self._rx = bytearray()
        self._ready = False
        self._busy = False
        self._dead = False
        self._pending: bytes | None = None
        self.not_ready = 0  # requests made while the child was still starting
        self.dropped = 0
        self.rendered = 0
        self.last_render_s = 0.0

    def _write(self, data: bytes | bytearray) -> None:
        view = memoryview(data)
        while view:
            n = os.write(self._out_fd, view)
            view = view[n:]

    def _next_message(self) -> bytes | None:
        """One complete message from the child if one has arrived (never blocks)."""
        try:
            while True:
                chunk = os.read(self._in_fd, 1 << 16)
                if not chunk:
                    if not self._dead:
                        log.warning("the depth render process exited (code %s): no more "
                                    "depth frames", self._proc.poll())
                    self._dead = True
                    break
                self._rx += chunk
                if len(chunk) < 1 << 16:
                    break
        except BlockingIOError:
            pass
        if len(self._rx) < _LEN.size:
            return None
        (n,) = _LEN.unpack_from(self._rx, 0)
        if len(self._rx) < _LEN.size + n:
            return None
        msg = bytes(self._rx[_LEN.size:_LEN.size + n])
        del self._rx[:_LEN.size + n]
        return msg

    def wait_ready(self, timeout_s: float = 60.0) -> bool:
        """Block until the child has built its model (optional: ``request`` works before)."""
        import select

        end = time.monotonic() + timeout_s
        while not self._ready and not self._dead:
            msg = self._next_message()
            if msg is not None:
                self._ready = msg == b"ready"
                break
            left = end - time.monotonic()
            if left <= 0:
                break
            select.select([self._in_fd], [], [], left)
        return self._ready

    def request(self, qpos: np.ndarray, utime: int) -> bool:
        """Ask for a frame of ``qpos`` at ``utime``; False (and counted) if still busy."""
        if not self._ready and not self.wait_ready(0.0):
            self.not_ready += 1
            return False
        if self._busy:
            self._collect()
            if self._busy:
                self.dropped += 1
                return False
        if self._req_q.size != qpos.size:
            self._req = bytearray(_LEN.size + _REQ.size + 8 * qpos.size)
            _LEN.pack_into(self._req, 0, _REQ.size + 8 * qpos.size)
            self._req_q = np.frombuffer(self._req, "<f8", qpos.size, _LEN.size + _REQ.size)
        _REQ.pack_into(self._req, _LEN.size, utime)
        self._req_q[:] = qpos
        try:
            self._write(self._req)
        except OSError:
            if not self._dead:
                log.warning("the depth render process is gone: no more depth frames")
            self._dead = True
            return False
        self._busy = True
        return True

    def _collect(self) -> None:
        if self._busy:
            msg = self._next_message()
            if msg is not None:
                self._pending = msg
                self._busy = False

    def poll(self) -> DepthFrame | None:
        """The newest finished frame, once; None if none finished since the last poll."""
        self._collect()
        raw, self._pending = self._pending, None
        if raw is None:
            return None
        vals = _REP.unpack_from(raw, 0)
        depth = np.frombuffer(raw, "<u2", offset=_REP.size).reshape(self._shape)
        self.rendered += 1
        self.last_render_s = vals[1]
        return DepthFrame(utime=vals[0], depth=depth, pos=np.array(vals[2:5]),
                          quat=np.array(vals[5:9]), render_s=vals[1])

    @property
    def alive(self) -> bool:
        return not self._dead and self._proc.poll() is None

    def close(self) -> None:
        """Stop the child process (at once if it is still starting up)."""
        if self._ready and not self._dead:
            try:
                self._write(_LEN.pack(0))
            except OSError:
                pass
        try:
            assert self._proc.stdin is not None
            self._proc.stdin.close()
        except OSError:
            pass
        try:
            self._proc.wait(timeout=1.0 if self._ready else 0.0)
        except Exception:
            self._proc.kill()
            self._proc.wait(timeout=2.0)
        if self._proc.stdout is not None:
            self._proc.stdout.close()


if __name__ == "__main__":
    raise SystemExit(_serve())
