"""Synthetic elevation maps for tests and the S3 benchmark: flat ground, a step, stairs,
stepping stones and a tilted plane, with optional noise and NaN holes, rasterised as whole
arrays; plus a walking sequence (a robot-centred map following a moving robot).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass

import cv2
import numpy as np

HeightFn = Callable[[np.ndarray, np.ndarray], np.ndarray]


def flat(z0: float = 0.0) -> HeightFn:
    """Level ground at height z0."""
    return lambda x, y: np.full(np.broadcast(x, y).shape, float(z0))


def step(edge_x: float = 0.0, height: float = 0.15, z0: float = 0.0) -> HeightFn:
    """A step up of `height` at x = edge_x (upper side x >= edge_x)."""
    return lambda x, y: z0 + height * (np.asarray(x) >= edge_x) + 0.0 * y


def stairs(start_x: float = 0.3, rise: float = 0.1, run: float = 0.4, steps: int = 5,
           z0: float = 0.0) -> HeightFn:
    """`steps` stairs up along +x from start_x, each `run` deep and `rise` high."""
    def fn(x: np.ndarray, y: np.ndarray) -> np.ndarray:
        k = np.clip(np.floor((np.asarray(x) - start_x) / run) + 1.0, 0.0, float(steps))
        return z0 + rise * k + 0.0 * y
    return fn


def tilted(slope_x: float = 0.2, slope_y: float = 0.1, z0: float = 0.0) -> HeightFn:
    """The plane z = z0 + slope_x x + slope_y y."""
    return lambda x, y: z0 + slope_x * np.asarray(x) + slope_y * np.asarray(y)


def stepping_stones(seed: int = 0, start_x: float = 0.4, stone: float = 0.45,
                    gap: float = 0.12, height_jitter: float = 0.06, pit_depth: float = 0.5,
                    z0: float = 0.0) -> HeightFn:
    """Square stones (side `stone`, `gap` apart) from start_x on, tops at z0 +- jitter, pits
    `pit_depth` deep between them; level ground before start_x (Table I's kind of course)."""
    rng = np.random.default_rng(seed)
    table = rng.uniform(-height_jitter, height_jitter, size=(64, 64))
    pitch = stone + gap

    def fn(x: np.ndarray, y: np.ndarray) -> np.ndarray:
        x, y = np.broadcast_arrays(np.asarray(x, float), np.asarray(y, float))
        u, v = (x - start_x) / pitch, (y + 0.5 * stone) / pitch
        i, j = np.floor(u).astype(int), np.floor(v).astype(int)
        on = ((u - i) * pitch < stone) & ((v - j) * pitch < stone)
        tops = z0 + table[i % 64, j % 64]
        z = np.where(on, tops, z0 - pit_depth)
        return np.where(x < start_x, z0, z)
    return fn


TERRAINS: dict[str, Callable[..., HeightFn]] = {
    "flat": flat, "step": step, "stairs": stairs, "tilted": tilted,
    "stones": stepping_stones,
}


def grid_xy(shape: tuple[int, int], resolution: float, origin_xy: np.ndarray
            ) -> tuple[np.ndarray, np.ndarray]:
    """World x, y of the cell centres; cell (i, j) at origin + (j, i) * resolution."""
    r, c = np.indices(shape, dtype=np.float64)
    return origin_xy[0] + c * resolution, origin_xy[1] + r * resolution


def render(height: HeightFn, shape: tuple[int, int] = (100, 100), resolution: float = 0.025,
           origin_xy: np.ndarray | None = None, noise_std: float = 0.0,
           nan_holes: int = 0, hole_radius_m: float = 0.06,
           rng: np.random.Generator | None = None) -> np.ndarray:
    """Rasterise `height` on the grid, add Gaussian noise and `nan_holes` NaN discs.

    The default origin centres the map on the world origin.
    """
    if origin_xy is None:
        origin_xy = -0.5 * (np.array(shape[::-1]) - 1) * resolution
    origin_xy = np.asarray(origin_xy, dtype=float)
    x, y = grid_xy(shape, resolution, origin_xy)
    z = np.asarray(height(x, y), dtype=np.float64)
    rng = rng if rng is not None else np.random.default_rng(0)
    if noise_std > 0.0:
        z = z + rng.normal(0.0, noise_std, size=z.shape)
    if nan_holes > 0:
        cx = rng.uniform(x.min(), x.max(), nan_holes)
        cy = rng.uniform(y.min(), y.max(), nan_holes)
        d2 = (x[..., None] - cx) ** 2 + (y[..., None] - cy) ** 2
        z[np.any(d2 <= hole_radius_m ** 2, axis=-1)] = np.nan
    return z


@dataclass(frozen=True)
class Frame:
    """One map of a walking sequence."""

    elevation: np.ndarray
    origin_xy: np.ndarray
    time_s: float
    robot_xy: np.ndarray


def walk(height: HeightFn, frames: int, seed: int = 0, shape: tuple[int, int] = (100, 100),
         resolution: float = 0.025, speed: float = 0.5, rate_hz: float = 30.0,
         start_xy: tuple[float, float] = (-0.8, 0.0), noise_std: float = 0.004,
         drift_step_m: float = 0.0005, nan_holes: int = 2) -> Iterator[Frame]:
    """A robot walking along +x at `speed` with a lateral sway; the map follows it in whole
    cells (robot-centred). Each frame has fresh noise, a random-walk height drift (what the
    drift correction leaves) and a few NaN occlusion holes.
    """
    rng = np.random.default_rng(seed)
    half = 0.5 * (np.array(shape[::-1]) - 1) * resolution
    drift = 0.0
    for k in range(frames):
        t = k / rate_hz
        robot = np.array([start_xy[0] + speed * t,
                          start_xy[1] + 0.04 * np.sin(2.0 * np.pi * t / 0.8)])
        origin = np.round(robot / resolution) * resolution - half
        drift += rng.normal(0.0, drift_step_m)
        z = render(height, shape, resolution, origin, noise_std, nan_holes, rng=rng) + drift
        yield Frame(z, origin, t, robot)


def camera_rotation(pitch_down_rad: float, yaw_rad: float = 0.0) -> np.ndarray:
    """World-from-optical rotation of a camera looking along +x (turned by yaw) and pitched
    down; optical frame z forward, x right, y down (as in `lcmtypes/depth_frame_t`)."""
    c, s = np.cos(pitch_down_rad), np.sin(pitch_down_rad)
    cy, sy = np.cos(yaw_rad), np.sin(yaw_rad)
    fwd = np.array([c * cy, c * sy, -s])
    right = np.array([sy, -cy, 0.0])
    down = np.cross(fwd, right)
    return np.column_stack((right, down, fwd))


def render_depth(height: HeightFn, position: np.ndarray, rotation: np.ndarray,
                 width: int, height_px: int, fx: float, fy: float, cx: float, cy: float,
                 max_range_m: float = 3.0, step_m: float = 0.025) -> np.ndarray:
    """Depth image (m, 0 = no return) of a heightfield by ray marching all pixels at once:
    coarse steps of `step_m` along each ray, then a linear refinement of the first crossing.
    Occlusions (the far side of a step down) come out as they would from a real camera."""
    v, u = np.mgrid[0:height_px, 0:width]
    rays = np.stack(((u - cx) / fx, (v - cy) / fy, np.ones(u.shape)), axis=-1).reshape(-1, 3)
    dirs = rays @ rotation.T                       # per unit of optical depth
    ts = np.arange(step_m, max_range_m + step_m, step_m)
    pts = position[None, None, :] + ts[None, :, None] * dirs[:, None, :]
    gap = pts[..., 2] - height(pts[..., 0], pts[..., 1])   # > 0 above the ground
    below = gap <= 0.0
    hit = below.any(axis=1)
    k = np.argmax(below, axis=1)
    k0 = np.maximum(k - 1, 0)
    rows = np.arange(len(k))
    g0, g1 = gap[rows, k0], gap[rows, k]
    with np.errstate(divide="ignore", invalid="ignore"):
        frac = np.where(k > 0, g0 / (g0 - g1), 0.0)
    depth = ts[k0] + np.clip(frac, 0.0, 1.0) * (ts[k] - ts[k0])
    depth = np.where(hit & (k > 0), depth, 0.0)
    return depth.reshape(height_px, width)


@dataclass(frozen=True)
class DepthFrame:
    """One camera frame of a walking robot: depth (m, 0 = none), intrinsics, estimated pose."""

    depth: np.ndarray
    fx: float
    fy: float
    cx: float
    cy: float
    camera_pos: np.ndarray          # estimated (with z drift), world
    camera_quat_wxyz: np.ndarray
    stance_foot: np.ndarray         # estimated contact point (same drift), world
    robot_xy: np.ndarray
    time_s: float


def _quat_wxyz(rot: np.ndarray) -> np.ndarray:
    """Quaternion (w, x, y, z) of a rotation matrix (Shepperd's method, w branch is enough
    for the pitched-down cameras used here; falls back to the largest diagonal otherwise)."""
    tr = np.trace(rot)
    if tr > 0.0:
        w = 0.5 * np.sqrt(1.0 + tr)
        return np.array([w, (rot[2, 1] - rot[1, 2]) / (4 * w), (rot[0, 2] - rot[2, 0]) / (4 * w),
                         (rot[1, 0] - rot[0, 1]) / (4 * w)])
    i = int(np.argmax(np.diag(rot)))
    j, k = (i + 1) % 3, (i + 2) % 3
    r = np.sqrt(1.0 + rot[i, i] - rot[j, j] - rot[k, k])
    q = np.empty(4)
    q[0] = (rot[k, j] - rot[j, k]) / (2 * r)
    q[1 + i] = 0.5 * r
    q[1 + j] = (rot[j, i] + rot[i, j]) / (2 * r)
    q[1 + k] = (rot[k, i] + rot[i, k]) / (2 * r)
    return q


def depth_walk(height: HeightFn, frames: int, seed: int = 0, speed: float = 0.5,
               rate_hz: float = 30.0, start_xy: tuple[float, float] = (-0.8, 0.0),
               render_size: tuple[int, int] = (106, 60), upsample: int = 2,
               pitch_down_deg: float = 55.0, camera_height_m: float = 1.0,
               depth_noise_m: float = 0.004, drift_step_m: float = 0.0005,
               step_period_s: float = 0.35) -> Iterator[DepthFrame]:
    """A pelvis-mounted, downward-pitched camera (D455-like field of view, 87 x 58 deg) on a
    robot walking along +x; the state estimate drifts in z and the stance foot alternates.

    Depth is ray-marched at `render_size` and repeated `upsample` times in each direction, so
    the map update sees a decimated D455 frame's point count at a fraction of the render cost.
    """
    rng = np.random.default_rng(seed)
    w, h = render_size
    fx = (w / 2) / np.tan(np.radians(43.5))
    fy = (h / 2) / np.tan(np.radians(29.0))
    rot = camera_rotation(np.radians(pitch_down_deg))
    quat = _quat_wxyz(rot)
    drift = 0.0
    for k in range(frames):
        t = k / rate_hz
        robot = np.array([start_xy[0] + speed * t,
                          start_xy[1] + 0.04 * np.sin(2.0 * np.pi * t / 0.8)])
        ground = float(height(np.array([robot[0]]), np.array([robot[1]]))[0])
        cam = np.array([robot[0] + 0.1, robot[1], ground + camera_height_m])
        depth = render_depth(height, cam, rot, w, h, fx, fy, (w - 1) / 2, (h - 1) / 2,
                             step_m=0.04)
        noisy = depth + rng.normal(0.0, depth_noise_m, depth.shape) * (depth > 0)
        if upsample > 1:
            noisy = np.repeat(np.repeat(noisy, upsample, axis=0), upsample, axis=1)
        side = 1.0 if int(t / step_period_s) % 2 == 0 else -1.0
        # the stance foot stands near the nominal step on ground that is flat for 6 cm around
        # it (as a foothold constraint would keep it), never on an edge
        nominal = robot + np.array([0.0, 0.1 * side])
        gx, gy = np.meshgrid(nominal[0] + np.linspace(-0.2, 0.2, 41),
                             nominal[1] + np.linspace(-0.15, 0.15, 31))
        zs = height(gx, gy).astype(np.float32)
        box = np.ones((13, 13), np.uint8)
        spread = cv2.dilate(zs, box) - cv2.erode(zs, box)     # height range within +-6 cm
        flat = spread < 0.01
        if not flat.any():
            flat = np.ones(zs.shape, bool)
        dist = np.where(flat, np.hypot(gx - nominal[0], gy - nominal[1]), np.inf)
        r_best, c_best = np.unravel_index(int(np.argmin(dist)), dist.shape)
        foot_xy = np.array([gx[r_best, c_best], gy[r_best, c_best]])
        foot_z = float(zs[r_best, c_best])
        drift += rng.normal(0.0, drift_step_m)
        s = float(upsample)
        yield DepthFrame(noisy, fx * s, fy * s, (w * s - 1) / 2, (h * s - 1) / 2,
                         cam + np.array([0.0, 0.0, drift]), quat,
                         np.array([*foot_xy, foot_z + drift]), robot, t)
