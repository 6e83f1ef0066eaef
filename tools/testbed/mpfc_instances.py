"""Random MPFC instances for tests and benchmarks: a robot near its walking orbit and a set of
1..20 convex footholds around it, like S3's output on a 3 m x 3 m map (Table VIII)."""

from __future__ import annotations

import numpy as np

from processes.mpfc.problem import MpfcModel
from processes.mpfc.solver import Instance
from runtime.geometry import Foothold


def random_polygon(rng: np.random.Generator, centre: np.ndarray, size: np.ndarray) -> np.ndarray:
    """A random convex polygon (3..8 vertices) inscribed in an ellipse of half-axes `size`."""
    k = int(rng.integers(3, 9))
    ang = np.sort(rng.uniform(0.0, 2.0 * np.pi, k))
    ang[0] = 0.0
    ang = np.sort(ang + rng.uniform(0, 2 * np.pi))
    rot = rng.uniform(0, np.pi)
    c, s = np.cos(rot), np.sin(rot)
    pts = np.column_stack([size[0] * np.cos(ang), size[1] * np.sin(ang)])
    pts = pts @ np.array([[c, s], [-s, c]])
    return centre + pts


def random_footholds(
    rng: np.random.Generator, m: int, origin: np.ndarray, yaw: float, vdes: np.ndarray
) -> list[Foothold]:
    """`m` footholds: stones scattered ahead of the robot, slopes up to ~15 deg, heights +-0.2 m.

    Roughly half of them near the nominal next footsteps so that the choice is not trivial.
    """
    out: list[Foothold] = []
    c, s = np.cos(yaw), np.sin(yaw)
    r2 = np.array([[c, -s], [s, c]])
    while len(out) < m:
        if rng.uniform() < 0.5:
            local = np.array([rng.uniform(-0.2, 0.2) + 0.4 * vdes[0] * rng.integers(1, 3),
                              rng.uniform(-0.35, 0.35)])
        else:
            local = rng.uniform([-0.6, -1.0], [1.4, 1.0])
        size = rng.uniform(0.05, 0.35, 2)
        verts = random_polygon(rng, origin[:2] + r2 @ local, size)
        tilt = rng.normal(0.0, 0.12, 2)
        normal = np.array([tilt[0], tilt[1], 1.0])
        z0 = origin[2] + rng.uniform(-0.2, 0.2)
        centre = verts.mean(axis=0)
        offset = float(normal @ np.array([centre[0], centre[1], z0]))
        try:
            out.append(Foothold.from_polygon(verts, normal, offset))
        except ValueError:
            continue
    return out


def random_instance(
    rng: np.random.Generator, model: MpfcModel, m: int, flat_start: bool = False
) -> Instance:
    """Robot near the periodic orbit of a random desired velocity, with `m` footholds."""
    p = model.params
    vdes = np.array([rng.uniform(-0.4, 1.0), rng.uniform(-0.3, 0.3)])
    stance = "left" if rng.uniform() < 0.5 else "right"
    sigma0 = -1.0 if stance == "left" else 1.0
    t_star = float(rng.uniform(0.02, p.t_s2s_s))
    # the periodic orbit's end-of-stance state for this stance (Appendix B), then back in time
    step = np.array([vdes[0] * p.t_s2s_s, vdes[1] * p.t_s2s_s + sigma0 * p.step_width_m])
    x0 = model.vs.L0 @ step + model.vs.D0 @ vdes
    x_c = model.expm_a(-t_star) @ x0
    x_c = x_c + rng.normal(0.0, 1.0, 4) * np.array([0.03, 0.03, 2.0, 2.0])
    yaw = 0.0 if flat_start else float(rng.uniform(-np.pi, np.pi))
    origin = np.array([rng.uniform(-2, 2), rng.uniform(-2, 2), rng.uniform(-0.2, 0.2)])
    footholds = random_footholds(rng, m, origin, yaw, vdes)
    return Instance(x_c, stance, origin, t_star, vdes, footholds, yaw)
