"""The one description of the robot: Cassie's MuJoCo model and the names every part uses.

The model is MuJoCo Menagerie's ``agility_cassie`` (never copied into the project): loaded
here for the sim, the estimator's and the OSC's kinematics and the dashboard alike. Offline
it needs ``MENAGERIE_ROOT``; when that is unset, a ``shared/menagerie`` folder beside the
checkout is used if there is one, passed to menagerie directly (the environment is left as
it is). The model is imported lazily: the supervisor and the tools that need no model do not
pay for mujoco.
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Any

#: the menagerie robot
ROBOT = "agility_cassie"
#: the legs, in the order every array of per-leg values uses
SIDES = ("left", "right")
#: the pelvis body, the root of the floating base
PELVIS_BODY = "cassie-pelvis"
#: the foot bodies, in SIDES order
FOOT_BODIES = tuple(f"{s}-foot" for s in SIDES)
#: the spring joints whose deflection measures each leg's load (Cassie's leaf springs)
SPRING_JOINTS = ("shin", "heel-spring")
#: the foot blade's contact points in the foot body frame: the two ends of its collision
#: capsule (menagerie cassie.xml), (front, rear): at the standing pose world x is +0.06, -0.10
FOOT_BLADE_ENDS = ((-0.052821, 0.092622, 0.0), (0.069746, -0.010224, 0.0))
FOOT_BLADE_RADIUS = 0.02
#: the RealSense D455 depth camera's mount on the pelvis, the one place of it (the sim's camera
#: renders from it, perception places its frames with it): its optical centre in the pelvis
#: frame (m), and its optical axis pitched this far below the pelvis x axis (deg). The values
#: the sim's camera was built with (commit 13b2f4a), not measured on a robot: a real Cassie's
#: mount goes here.
CAMERA_MOUNT_POS_M = (0.09, 0.0, 0.02)
CAMERA_PITCH_DOWN_DEG = 50.0


def mount_rotation(pitch_down_deg: float) -> Any:
    """The depth camera's mount on the pelvis: rotation pelvis <- optical frame (z forward,
    x right, y down), pitched down by ``pitch_down_deg`` (the sim's camera and the map's
    placement of it must agree: one formula)."""
    import numpy as np

    p = math.radians(pitch_down_deg)
    z = np.array([math.cos(p), 0.0, -math.sin(p)])  # the optical axis
    x = np.array([0.0, -1.0, 0.0])  # image right = pelvis -y
    return np.column_stack([x, np.cross(z, x), z])


_SHARED = Path(__file__).resolve().parents[2] / "shared" / "menagerie"


def menagerie_root() -> Path | None:
    """Where the menagerie models are: ``$MENAGERIE_ROOT``, else the shared folder beside the
    checkout, else None (menagerie's own cache, which may download)."""
    if root := os.environ.get("MENAGERIE_ROOT"):
        return Path(root)
    return _SHARED if _SHARED.is_dir() else None


def _cache() -> Any:
    import mujoco_menagerie

    return mujoco_menagerie.Cache(root=menagerie_root())


def load_model() -> Any:
    """Cassie and its floor (the menagerie scene) as a compiled ``mujoco.MjModel``."""
    import mujoco_menagerie

    return mujoco_menagerie.load(ROBOT, cache=_cache())


def load_spec() -> Any:
    """The same scene as an editable ``mujoco.MjSpec`` (the sim adds terrain and a holder)."""
    import mujoco_menagerie

    return mujoco_menagerie.get(ROBOT).spec(cache=_cache())
