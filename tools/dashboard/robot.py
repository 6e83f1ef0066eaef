"""Cassie from the MuJoCo model: its visual meshes posed at the joint angles, or a stick figure.

The menagerie model the rest of the project uses is loaded once. Its mesh geoms are turned
into Rerun meshes in their bodies' frames (``mesh_parts``) and logged once, as static data
(``log_meshes``); per robot frame only ``mj_kinematics`` runs (a few microseconds) and each
body's world pose is sent (``Skeleton.pose``). When the model has no usable meshes the leg
chains are drawn as lines instead; without the model at all (no ``MENAGERIE_ROOT`` or
mujoco) the dashboard still shows the pelvis pose and the feet from ground truth.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Any

import numpy as np

from runtime.robot import SIDES, load_model

log = logging.getLogger(__name__)

#: Bodies from the pelvis down each leg, in order (menagerie agility_cassie names).
LEG_CHAIN = ("hip-roll", "hip-yaw", "hip-pitch", "knee", "shin", "tarsus", "foot")

#: Geom groups MuJoCo's own viewer shows by default; Cassie's collision shapes are in group 3.
VISIBLE_GROUPS = (0, 1, 2)

#: Entity under which each body's meshes are logged (``<root>/<body>/<geom>``).
MESH_ROOT = "world/robot/meshes"
#: Entity that carries every body's world pose, one Transform3D row per body and frame.
FRAMES_ENTITY = "world/robot/body_frames"
#: Prefix of the named transform frame of each body (``cassie/<body name>``).
FRAME_PREFIX = "cassie/"
#: The frame the body poses are given in: the implicit frame of the ``world`` entity.
WORLD_FRAME = "tf#/world"


@dataclass(frozen=True)
class MeshPart:
    """One visual mesh geom in its body's frame, with one normal and colour per vertex."""

    body: str
    geom: int
    positions: np.ndarray  # (n, 3) float32, in the body's frame
    normals: np.ndarray  # (n, 3) float32, unit length
    triangles: np.ndarray  # (m, 3) uint32, indices into positions
    rgba: np.ndarray  # (4,) uint8: the material's colour, else the geom's
    colors: np.ndarray | None  # (n, 3) uint8 from the material's texture, None when untextured


@dataclass(frozen=True)
class Pose:
    """One robot frame from forward kinematics."""

    legs: np.ndarray  # (2, len(LEG_CHAIN) + 1, 3): pelvis-to-foot points per leg
    body_pos: np.ndarray  # (bodies, 3): world position of each meshed body
    body_quat: np.ndarray  # (bodies, 4): world orientation, x y z w (Rerun's order)


def _quat_to_mat(quat_wxyz: np.ndarray) -> np.ndarray:
    """Rotation matrix of a unit quaternion given w, x, y, z (MuJoCo's order)."""
    w, x, y, z = (float(v) for v in quat_wxyz)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def _texture_rgb(model: Any, mat: int) -> tuple[np.ndarray, np.ndarray] | None:
    """(image (h, w, 3) uint8, texrepeat (2,)) of a material's 2D colour texture, or None."""
    import mujoco

    if mat < 0:
        return None
    tex = int(model.mat_texid[mat, int(mujoco.mjtTextureRole.mjTEXROLE_RGB)])
    if tex < 0 or int(model.tex_type[tex]) != int(mujoco.mjtTexture.mjTEXTURE_2D):
        return None
    h, w, c = int(model.tex_height[tex]), int(model.tex_width[tex]), int(model.tex_nchannel[tex])
    if c < 3:
        return None
    adr = int(model.tex_adr[tex])
    img = np.asarray(model.tex_data[adr : adr + h * w * c], np.uint8).reshape(h, w, c)[..., :3]
    return img, np.asarray(model.mat_texrepeat[mat], np.float64)


def _sample(img: np.ndarray, repeat: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Nearest texel of each (u, v); MuJoCo's v runs down the image rows (row 0 is v = 0)."""
    h, w = img.shape[:2]
    u = np.mod(uv[:, 0] * repeat[0], 1.0)
    v = np.mod(uv[:, 1] * repeat[1], 1.0)
    cols = np.clip((u * w).astype(np.int64), 0, w - 1)
    rows = np.clip((v * h).astype(np.int64), 0, h - 1)
    return img[rows, cols]


def mesh_parts(model: Any) -> list[MeshPart]:
    """Every visible mesh geom of the robot (not of the world body) as a ``MeshPart``.

    MuJoCo indexes positions, normals and texture coordinates of a face corner separately;
    Rerun wants one index per vertex, so each distinct (position, normal, texcoord) corner
    becomes one vertex. The geom's pose in its body is applied here, once, so that per frame
    only the body poses need sending.
    """
    import mujoco

    parts: list[MeshPart] = []
    for g in range(int(model.ngeom)):
        mesh = int(model.geom_dataid[g])
        body = int(model.geom_bodyid[g])
        if (
            int(model.geom_type[g]) != int(mujoco.mjtGeom.mjGEOM_MESH)
            or mesh < 0
            or body == 0
            or int(model.geom_group[g]) not in VISIBLE_GROUPS
            or float(model.geom_rgba[g, 3]) == 0.0
        ):
            continue
        va, vn = int(model.mesh_vertadr[mesh]), int(model.mesh_vertnum[mesh])
        fa, fn = int(model.mesh_faceadr[mesh]), int(model.mesh_facenum[mesh])
        na = int(model.mesh_normaladr[mesh])
        ta, tn = int(model.mesh_texcoordadr[mesh]), int(model.mesh_texcoordnum[mesh])
        if vn == 0 or fn == 0:
            continue
        corners = [
            model.mesh_face[fa : fa + fn].reshape(-1),
            model.mesh_facenormal[fa : fa + fn].reshape(-1),
        ]
        mat = int(model.geom_matid[g])
        texture = _texture_rgb(model, mat) if tn > 0 else None
        if texture is not None:
            corners.append(model.mesh_facetexcoord[fa : fa + fn].reshape(-1))
        # one int64 per corner (mixed radix), as np.unique of rows is ~10 times slower
        keys = np.zeros(3 * fn, np.int64)
        for idx in corners:
            keys = keys * (int(idx.max()) + 1) + idx
        _, first, inverse = np.unique(keys, return_index=True, return_inverse=True)
        unique = np.stack(corners, axis=1)[first]
        rot = _quat_to_mat(model.geom_quat[g])
        pos = model.mesh_vert[va : va + vn][unique[:, 0]] @ rot.T + model.geom_pos[g]
        nrm = model.mesh_normal[na + unique[:, 1]] @ rot.T
        nrm /= np.maximum(np.linalg.norm(nrm, axis=1, keepdims=True), 1e-12)
        rgba = model.mat_rgba[mat] if mat >= 0 else model.geom_rgba[g]
        rgba8 = np.clip(np.round(np.asarray(rgba) * 255.0), 0, 255).astype(np.uint8)
        colors = None
        if texture is not None:
            img, repeat = texture
            texel = _sample(img, repeat, model.mesh_texcoord[ta + unique[:, 2]])
            colors = np.clip(np.round(texel * (rgba8[:3] / 255.0)), 0, 255).astype(np.uint8)
        parts.append(
            MeshPart(
                body=str(mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, body) or f"body{body}"),
                geom=g,
                positions=np.ascontiguousarray(pos, np.float32),
                normals=np.ascontiguousarray(nrm, np.float32),
                triangles=np.ascontiguousarray(inverse.reshape(fn, 3), np.uint32),
                rgba=rgba8,
                colors=colors,
            )
        )
    return parts


class Skeleton:
    """Forward kinematics of Cassie for a MuJoCo qpos (nq 35, floating base first): the leg
    chains as points and, when ``meshes`` is set, the visual meshes and each body's pose."""

    def __init__(self, model: Any, meshes: bool = True) -> None:
        import mujoco

        self._mujoco = mujoco
        self.model = model
        self.data = mujoco.MjData(model)
        self.nq = int(model.nq)
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
        self._chain_ids = np.array(self.chains)
        self.parts: list[MeshPart] = mesh_parts(model) if meshes else []
        names = list(dict.fromkeys(p.body for p in self.parts))  # bodies in model order
        self.bodies: list[str] = names
        self._body_ids = np.array(
            [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, n) for n in names], np.int64
        )
        #: the named transform frame of each meshed body, in ``bodies`` order
        self.frames: list[str] = [FRAME_PREFIX + n for n in names]

    @property
    def has_meshes(self) -> bool:
        """True when the robot is drawn from meshes (else as the leg chains' lines)."""
        return bool(self.parts)

    def pose(self, q: np.ndarray) -> Pose:
        """Leg points and body poses for ``q`` from one ``mj_kinematics``."""
        d = self.data
        d.qpos[:] = q
        self._mujoco.mj_kinematics(self.model, d)
        quat = d.xquat[self._body_ids]
        return Pose(
            legs=d.xpos[self._chain_ids],
            body_pos=d.xpos[self._body_ids],
            body_quat=quat[:, [1, 2, 3, 0]],
        )

    def legs(self, q: np.ndarray) -> np.ndarray:
        """World positions (2 legs, len(LEG_CHAIN) + 1 points, 3) of the chain for ``q``."""
        d = self.data
        d.qpos[:] = q
        self._mujoco.mj_kinematics(self.model, d)
        return d.xpos[self._chain_ids]


def log_meshes(rec: Any, skeleton: Skeleton) -> int:
    """Log each mesh part once, as static data in its body's named frame; returns how many.

    Per frame the batcher then sends only the body poses (``FRAMES_ENTITY``), so the drawn
    robot costs one send a batch however many meshes it has.
    """
    import rerun as rr

    for part in skeleton.parts:
        path = f"{MESH_ROOT}/{rr.escape_entity_path_part(part.body)}/geom_{part.geom}"
        mesh = rr.Mesh3D(
            vertex_positions=part.positions,
            triangle_indices=part.triangles,
            vertex_normals=part.normals,
            vertex_colors=part.colors,
            albedo_factor=None if part.colors is not None else part.rgba,
        )
        rec.log(path, mesh, rr.CoordinateFrame(FRAME_PREFIX + part.body), static=True)
    return len(skeleton.parts)


def load_skeleton(meshes: bool = True) -> Skeleton | None:
    """The Cassie model (meshes unless ``meshes`` is False), or None (with one log line
    saying why) when it cannot be loaded."""
    try:
        model = load_model()  # (the one loader: runtime.robot)
    except Exception as exc:  # optional feature: the dashboard works without it
        log.warning("no robot model (could not load the Cassie model: %s)", exc)
        return None
    try:
        skeleton = Skeleton(model, meshes=meshes)
    except Exception as exc:  # meshes unusable: the stick figure still works
        log.warning("no robot meshes (%s); drawing the leg skeleton", exc)
        try:
            skeleton = Skeleton(model, meshes=False)
        except Exception as exc2:
            log.warning("no leg skeleton either (%s)", exc2)
            return None
    skeleton.pose(model.qpos0)  # warm up once
    if meshes and not skeleton.has_meshes:
        log.warning("the Cassie model has no visible meshes; drawing the leg skeleton")
    return skeleton
