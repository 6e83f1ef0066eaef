"""Cassie from MuJoCo Menagerie, with terrain geometry, and a clean standing pose by IK.

The model comes from ``runtime.robot`` (the one loader; offline: ``MENAGERIE_ROOT``), edited as an
``MjSpec``: the terrain's boxes become static geoms, ``impratio`` is raised (10 cuts the
creep of planted feet from about 1 cm to 2 mm over 10 s). The ``home`` keyframe leaves the
rod closures about 1.5 mm off, so the start pose is solved by IK: rods closed, springs at
rest, feet flat on the start surface, pelvis level at the requested height.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import mujoco
import numpy as np
from scipy.optimize import least_squares

from runtime.cassie_packets import JOINT_NAMES, MOTOR_NAMES
from runtime.robot import FOOT_BODIES, SIDES, load_spec
from runtime.robot import SPRING_JOINTS as LEG_SPRINGS
from sim.terrain import Terrain

#: every spring joint by its full name, in SIDES order
SPRING_JOINTS = tuple(f"{s}-{j}" for s in SIDES for j in LEG_SPRINGS)
TERRAIN_RGBA = ((0.55, 0.55, 0.5, 1.0), (0.45, 0.5, 0.55, 1.0))


HOLDER_BODY = "pelvis-holder"
HOLDER_EQ = "pelvis-holder"
#: the obstacle cubes' bodies are named CUBE_PREFIX + index (``build_model(cubes=...)``)
CUBE_PREFIX = "obstacle-cube-"
#: where the cubes wait until they are dropped: far outside the camera's range, on a plate
CUBE_PARKING_XY = (-40.0, 40.0)
CUBE_DENSITY_KG_M3 = 30.0  # foam, as the paper's tossed cubes (Section VIII-D-4)


def build_model(
    terrain: Terrain | None = None,
    impratio: float = 10.0,
    holder_solref: tuple[float, float] = (0.01, 1.0),
    cubes: int = 0,
    cube_size_m: float = 0.15,
) -> mujoco.MjModel:
    """Compile Cassie with the terrain's boxes as static geoms (group 0, collide with feet),
    plus the start-up holder: a mocap body welded to the pelvis by a soft weld (inactive
    until ``SimCore`` turns it on; ``holder_solref`` = time constant, damping ratio); and
    ``cubes`` free foam cubes of side ``cube_size_m`` parked on a plate far away until the
    sim drops them (``SimCore``, ``DropsConfig``): their joints come after the robot's, so
    the robot's qpos and qvel are the first entries still."""
    spec = load_spec()
    spec.option.impratio = impratio
    pelvis = spec.body("cassie-pelvis")
    anchor = spec.worldbody.add_body()
    anchor.name = HOLDER_BODY
    anchor.mocap = True
    anchor.pos = list(pelvis.pos)  # same pose as the pelvis at qpos0: the weld's relpose is 1
    anchor.quat = list(pelvis.quat)
    weld = spec.add_equality()
    weld.name = HOLDER_EQ
    weld.type = mujoco.mjtEq.mjEQ_WELD
    weld.objtype = mujoco.mjtObj.mjOBJ_BODY
    weld.name1 = HOLDER_BODY
    weld.name2 = "cassie-pelvis"
    weld.solref = list(holder_solref)
    weld.solimp = [0.99, 0.999, 0.001, 0.5, 2.0]
    weld.active = False
    floor = spec.geom("floor")
    if terrain is not None:
        if terrain.ground_z is None:
            spec.delete(floor)
        else:
            floor.pos = [0.0, 0.0, terrain.ground_z]
        for i, box in enumerate(terrain.boxes):
            g = spec.worldbody.add_geom()
            g.name = f"terrain-{i}"
            g.type = mujoco.mjtGeom.mjGEOM_BOX
            g.size = [0.5 * box.size[0], 0.5 * box.size[1], 0.5 * box.size[2]]
            g.pos = list(box.center)
            g.quat = list(box.quat_wxyz)
            g.contype = 0
            g.conaffinity = 15
            g.condim = 3
            g.group = 0
            g.rgba = list(TERRAIN_RGBA[i % 2])
    if cubes > 0:
        _add_cubes(spec, cubes, cube_size_m,
                   0.0 if terrain is None or terrain.ground_z is None else terrain.ground_z)
    return spec.compile()


def robot_size(m: mujoco.MjModel) -> tuple[int, int]:
    """(nq, nv) of the robot: the qpos and dofs before the first obstacle cube's joint (the
    whole model's without cubes)."""
    body = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, f"{CUBE_PREFIX}0")
    if body < 0:
        return int(m.nq), int(m.nv)
    j = int(m.body_jntadr[body])
    return int(m.jnt_qposadr[j]), int(m.jnt_dofadr[j])


def cube_bodies(m: mujoco.MjModel) -> list[int]:
    """The obstacle cubes' body ids, in order."""
    out = []
    while (b := mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, f"{CUBE_PREFIX}{len(out)}")) >= 0:
        out.append(b)
    return out


def _add_cubes(spec: mujoco.MjSpec, count: int, size: float, ground_z: float) -> None:
    """The parking plate and ``count`` cubes resting on it in a row."""
    px, py = CUBE_PARKING_XY
    plate = spec.worldbody.add_geom()
    plate.name = "obstacle-parking"
    plate.type = mujoco.mjtGeom.mjGEOM_BOX
    plate.size = [0.5 * count * size + 1.0, 1.0, 0.05]
    plate.pos = [px, py, ground_z - 0.05]
    plate.contype, plate.conaffinity = 0, 15  # as the terrain: static, everything lands on it
    for i in range(count):
        body = spec.worldbody.add_body()
        body.name = f"{CUBE_PREFIX}{i}"
        body.pos = [px - 0.5 * count * size + (i + 0.5) * 2 * size, py, ground_z + 0.5 * size]
        body.add_freejoint()
        g = body.add_geom()
        g.type = mujoco.mjtGeom.mjGEOM_BOX
        g.size = [0.5 * size] * 3
        g.density = CUBE_DENSITY_KG_M3
        # (bit 8 of its own: it lands on the ground, the terrain, other cubes and the robot)
        g.contype, g.conaffinity, g.condim = 8, 15, 3
        g.group = 1  # the depth camera sees groups 0 and 1
        g.rgba = [0.9, 0.5, 0.1, 1.0]


@dataclass(frozen=True)
class CassieIndices:
    """Addresses into qpos/qvel/ctrl/sensordata that the target PC reads every tick."""

    motor_qpos: np.ndarray  # (10,) int
    motor_dof: np.ndarray
    joint_qpos: np.ndarray  # (8,) passive joints, JOINT_NAMES order
    joint_dof: np.ndarray
    gear: np.ndarray  # (10,) joint torque = gear * ctrl
    torque_limit: np.ndarray  # (10,) joint-side torque limit, N m
    pelvis_body: int
    imu_site: int
    accel_adr: int  # sensordata address of the accelerometer (3 values)
    foot_bodies: tuple[int, int]
    foot_geoms: tuple[int, int]  # collision capsules
    holder_eq: int  # the pelvis holder's weld (-1 if the model has none)
    holder_mocap: int  # its mocap index

    @classmethod
    def of(cls, m: mujoco.MjModel) -> CassieIndices:
        def jid(name: str) -> int:
            return mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, name)

        motor_j = [jid(n) for n in MOTOR_NAMES]
        passive_j = [jid(n) for n in JOINT_NAMES]
        act = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_ACTUATOR, n) for n in MOTOR_NAMES]
        if act != list(range(len(MOTOR_NAMES))):
            raise RuntimeError(f"unexpected actuator order in the model: {act}")
        gear = m.actuator_gear[act, 0].copy()
        limit = gear * np.abs(m.actuator_ctrlrange[act]).max(axis=1)
        accel = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SENSOR, "pelvis-linear-acceleration")
        feet = tuple(mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, n) for n in FOOT_BODIES)
        foot_geoms = tuple(
            int(np.flatnonzero((m.geom_bodyid == b) & (m.geom_contype != 0))[0]) for b in feet
        )
        return cls(
            motor_qpos=m.jnt_qposadr[motor_j].copy(),
            motor_dof=m.jnt_dofadr[motor_j].copy(),
            joint_qpos=m.jnt_qposadr[passive_j].copy(),
            joint_dof=m.jnt_dofadr[passive_j].copy(),
            gear=gear,
            torque_limit=limit,
            pelvis_body=mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "cassie-pelvis"),
            imu_site=mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, "imu"),
            accel_adr=int(m.sensor_adr[accel]),
            foot_bodies=feet,  # type: ignore[arg-type]
            foot_geoms=foot_geoms,  # type: ignore[arg-type]
            holder_eq=mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_EQUALITY, HOLDER_EQ),
            holder_mocap=int(m.body_mocapid[max(
                mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, HOLDER_BODY), 0)]),
        )


def foot_endpoints(m: mujoco.MjModel, d: mujoco.MjData, geom: int) -> np.ndarray:
    """The two end points (2, 3) of a foot's collision capsule axis, world frame."""
    axis = d.geom_xmat[geom].reshape(3, 3)[:, 2] * m.geom_size[geom, 1]
    return np.stack([d.geom_xpos[geom] - axis, d.geom_xpos[geom] + axis])


def closure_residual(m: mujoco.MjModel, d: mujoco.MjData) -> np.ndarray:
    """Position error (metres) of every ``connect`` equality, after ``mj_kinematics``."""
    out = []
    for i in range(m.neq):
        if m.eq_type[i] != mujoco.mjtEq.mjEQ_CONNECT:
            continue
        b1, b2 = m.eq_obj1id[i], m.eq_obj2id[i]
        p1 = d.xpos[b1] + d.xmat[b1].reshape(3, 3) @ m.eq_data[i, 0:3]
        p2 = d.xpos[b2] + d.xmat[b2].reshape(3, 3) @ m.eq_data[i, 3:6]
        out.append(p1 - p2)
    return np.concatenate(out)


def standing_pose(
    m: mujoco.MjModel, pelvis_height: float = 0.95, ground_z: float = 0.0, foot_y: float = 0.135
) -> np.ndarray:
    """qpos of a symmetric standing pose: rods closed, springs at rest, feet flat at
    ``ground_z``, pelvis level at ``ground_z + pelvis_height``, CoM above the feet in x."""
    q = _standing_pose_cached(_model_key(m), pelvis_height, foot_y)
    q = q.copy()
    q[2] += ground_z
    return q


_MODELS: dict[int, mujoco.MjModel] = {}


def _model_key(m: mujoco.MjModel) -> int:
    # the IK only depends on the robot, not the terrain: key on the robot's kinematics
    key = hash((m.nq, m.body_pos.tobytes(), m.body_quat.tobytes(), m.eq_data.tobytes()))
    _MODELS[key] = m
    return key


@functools.lru_cache(maxsize=8)
def _standing_pose_cached(key: int, pelvis_height: float, foot_y: float) -> np.ndarray:
    m = _MODELS[key]
    d = mujoco.MjData(m)
    idx = CassieIndices.of(m)
    q0 = m.key_qpos[0].copy() if m.nkey else d.qpos.copy()
    nq_robot, nv_robot = robot_size(m)
    q0[nq_robot:] = m.qpos0[nq_robot:]  # obstacle cubes, if any: parked
    q0[0:3] = [0.0, 0.0, pelvis_height]
    q0[3:7] = [1.0, 0.0, 0.0, 0.0]
    springs = [m.jnt_qposadr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, n)]
               for n in SPRING_JOINTS]
    q0[springs] = 0.0
    spring_dofs = {int(m.jnt_dofadr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, n)])
                   for n in SPRING_JOINTS}
    free = np.array([i for i in range(6, nv_robot) if i not in spring_dofs])
    yaw_dofs = idx.motor_dof[[1, 6]]
    radius = m.geom_size[list(idx.foot_geoms), 0]
    dq = np.zeros(m.nv)
    q = np.empty(m.nq)

    def pose(x: np.ndarray) -> np.ndarray:
        dq[free] = x
        q[:] = q0
        mujoco.mj_integratePos(m, q, dq, 1.0)
        return q

    def residual(x: np.ndarray) -> np.ndarray:
        d.qpos[:] = pose(x)
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        ends = [foot_endpoints(m, d, g) for g in idx.foot_geoms]
        mids = [e.mean(axis=0) for e in ends]
        com_x = d.subtree_com[idx.pelvis_body, 0]
        r = [
            1e3 * closure_residual(m, d),
            1e3 * np.array([ends[0][0, 2] - radius[0], ends[0][1, 2] - radius[0],
                            ends[1][0, 2] - radius[1], ends[1][1, 2] - radius[1]]),
            1e2 * np.array([ends[0][0, 1] - ends[0][1, 1], ends[1][0, 1] - ends[1][1, 1],
                            mids[0][1] - foot_y, mids[1][1] + foot_y,
                            mids[0][0] - mids[1][0], 0.5 * (mids[0][0] + mids[1][0]) - com_x]),
            1e-2 * x,
            1e-1 * dq[yaw_dofs],
        ]
        return np.concatenate(r)

    sol = least_squares(residual, np.zeros(len(free)), xtol=1e-12, ftol=1e-12, gtol=1e-12,
                        max_nfev=2000)
    return pose(sol.x).copy()


def pose_report(m: mujoco.MjModel, qpos: np.ndarray) -> dict[str, float]:
    """Figures describing a pose: closure error, foot heights and tilt, CoM offset."""
    d = mujoco.MjData(m)
    d.qpos[:] = qpos
    mujoco.mj_kinematics(m, d)
    mujoco.mj_comPos(m, d)
    idx = CassieIndices.of(m)
    ends = [foot_endpoints(m, d, g) for g in idx.foot_geoms]
    r = m.geom_size[idx.foot_geoms[0], 0]
    mids = np.array([e.mean(axis=0) for e in ends])
    return {
        "pelvis_z_m": float(qpos[2]),
        "closure_max_m": float(np.abs(closure_residual(m, d)).max()),
        "foot_z_min_m": float(min(e[:, 2].min() for e in ends) - r),
        "foot_z_max_m": float(max(e[:, 2].max() for e in ends) - r),
        "com_minus_feet_x_m": float(d.subtree_com[idx.pelvis_body, 0] - mids[:, 0].mean()),
        "foot_y_m": float(mids[0, 1]),
    }
