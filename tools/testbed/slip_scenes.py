"""The scenes of Bartlett & Manchester's Table I for the SLIP guide planner, built from the
sim's terrain generators: flat ground, stepping stones, a chasm and a staircase up.

The paper does not give its scenes' sizes; ours are Cassie's: the stones are the MPFC
paper's Table I stones (``sim.terrain.stones``, 35-40 cm, 16-21 cm gaps, +-7.5 cm heights),
the chasm a 35 cm gap across the path, the stairs the generator's 15 cm x 27 cm steps. Each
start stands 20-35 cm before the feature, so that even the 1.5 s horizon (0.48 m at
0.32 m/s) plans over it. A trial moves the start by up to +-5 cm along the path (and draws
new stones): ten trials are ten problems, not one problem timed ten times.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from processes.slip_guide.candidates import Candidates, sample_footholds, surface_height
from processes.slip_guide.params import SlipParams
from processes.slip_guide.planner import reference_path
from runtime.geometry import Foothold
from sim import terrain as T

SCENES = ("flat", "stones", "chasm", "stairs")
CHASM_GAP_M = (0.45, 0.80)  # x extent of the chasm's gap
SPEED_MPS = 0.32  # Section IV-A: the desired forward velocity of every Table I trial
START_X_M = {"flat": 0.0, "stones": 0.25, "chasm": 0.2, "stairs": 0.35}


@dataclass(frozen=True)
class Scene:
    """A terrain's footholds (the planner's input) and the CoM's start (x, y)."""

    name: str
    terrain: T.Terrain
    start_xy: tuple[float, float]

    @property
    def footholds(self) -> tuple[Foothold, ...]:
        return self.terrain.landing_surfaces


def chasm(gap: tuple[float, float] = CHASM_GAP_M, width: float = 2.0) -> T.Terrain:
    """Flat ground with a gap across the path (x in ``gap``) over a pit 0.5 m deep."""
    ends = ((-2.0, gap[0]), (gap[1], 6.0))
    return T.from_boxes([T.Box(center=(0.5 * (a + b), 0.0, -0.25), size=(b - a, width, 0.5))
                         for a, b in ends], ground_z=-0.5)


def scene(name: str, trial: int = 0) -> Scene:
    """Scene ``name`` of Table I, trial ``trial`` (its start jitter and, for the stones,
    its draw of the stones)."""
    rng = np.random.default_rng(trial)
    x0 = START_X_M[name] + float(rng.uniform(-0.05, 0.05))
    if name == "flat":
        terrain = T.flat()
    elif name == "stones":
        terrain = T.stones(seed=trial)
    elif name == "chasm":
        terrain = chasm()
    elif name == "stairs":
        terrain = T.stairs()
    else:
        raise ValueError(f"unknown scene {name!r} (allowed: {', '.join(SCENES)})")
    return Scene(name, terrain, (x0, 0.0))


def problem(sc: Scene, params: SlipParams, speed_mps: float = SPEED_MPS
            ) -> tuple[np.ndarray, np.ndarray, Candidates]:
    """The path s*, ds*/dt and candidates of one scene: the footholds sampled within reach
    of the path."""
    holds = sc.footholds
    s_ref, v_ref = reference_path(np.asarray(sc.start_xy), 0.0, speed_mps, params,
                                  lambda xy: surface_height(holds, xy))
    r = params.reach_m
    bounds = (float(s_ref[:, 0].min() - r), float(s_ref[:, 0].max() + r),
              float(s_ref[:, 1].min() - r), float(s_ref[:, 1].max() + r))
    cands = sample_footholds(holds, params.candidate_spacing_m, bounds)
    return s_ref, v_ref, cands
