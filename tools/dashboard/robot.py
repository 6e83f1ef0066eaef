"""A stick-figure Cassie: world positions of the leg joints from MuJoCo forward kinematics.

Only ``mj_kinematics`` runs (tens of microseconds), at the dashboard's robot rate, on the
menagerie model the rest of the project uses. Without the model (no ``MENAGERIE_ROOT`` or
mujoco) the dashboard still shows the pelvis pose and the feet from ground truth.
"""

from __future__ import annotations

import logging
import os
from pathlib import Path

import numpy as np

log = logging.getLogger(__name__)

#: Bodies from the pelvis down each leg, in order (menagerie agility_cassie names).
LEG_CHAIN = ("hip-roll", "hip-yaw", "hip-pitch", "knee", "shin", "tarsus", "foot")
SIDES = ("left", "right")


class Skeleton:
    """Forward kinematics of the leg chains for a MuJoCo qpos (nq 35, floating base first)."""

    def __init__(self, model: object) -> None:
        import mujoco

        self._mujoco = mujoco
        self.model = model
        self.data = mujoco.MjData(model)
        self.nq = int(model.nq)  # type: ignore[attr-defined]
        pelvis = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "cassie-pelvis")
        self.chains: list[list[int]] = []
        for side in SIDES:
            ids = [pelvis]
            for name in LEG_CHAIN:
                bid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, f"{side}-{name}")
                if bid < 0:
                    raise ValueError(f"the model has no body {side}-{name}")
                ids.append(bid)
            self.chains.append(ids)

    def legs(self, q: np.ndarray) -> np.ndarray:
        """World positions (2 legs, len(LEG_CHAIN) + 1 points, 3) of the chain for ``q``."""
        d = self.data
        d.qpos[:] = q
        self._mujoco.mj_kinematics(self.model, d)
        return np.stack([d.xpos[ids] for ids in self.chains])


def load_skeleton() -> Skeleton | None:
    """The Cassie skeleton, or None (with one log line saying why) when it cannot be loaded."""
    if not os.environ.get("MENAGERIE_ROOT"):
        shared = Path(__file__).resolve().parents[3] / "shared" / "menagerie"
        if shared.is_dir():
            os.environ["MENAGERIE_ROOT"] = str(shared)
    try:
        import mujoco_menagerie

        skeleton = Skeleton(mujoco_menagerie.load("agility_cassie"))
        skeleton.legs(skeleton.model.qpos0)  # type: ignore[attr-defined]  # warm up once
        return skeleton
    except Exception as exc:  # optional feature: the dashboard works without it
        log.warning("no leg skeleton (could not load the Cassie model: %s)", exc)
        return None
