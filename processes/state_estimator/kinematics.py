"""Cassie leg kinematics from the MuJoCo model, in the pelvis frame, for the state estimator.

The target PC measures 18 joints (10 motors, 8 passive: shin and heel springs, tarsus, foot
crank). The model has 28 joint coordinates: the two closed-chain rods (achilles ball joint,
plantar hinge) are not measured, so they are solved here from their ``connect`` closures, in
closed form, so that the published ``q``/``v`` satisfy the loop closures an OSC relies on.

Everything is computed with the pelvis at the origin with identity orientation (the "body
frame"); the estimator rotates results into the world with its base estimate. One private
``MjData``, preallocated buffers, no allocation per call beyond numpy temporaries of size 3.
"""

from __future__ import annotations

import math

import mujoco
import numba
import numpy as np

from runtime.cassie_packets import JOINT_NAMES, MOTOR_NAMES

SIDES = ("left", "right")
#: the spring joints whose deflection measures the load on each leg (Cassie's leaf springs)
SPRING_JOINTS = ("shin", "heel-spring")


def load_model() -> mujoco.MjModel:
    """Cassie from MuJoCo Menagerie (offline: set ``MENAGERIE_ROOT``)."""
    import mujoco_menagerie

    return mujoco_menagerie.load("agility_cassie")


def _quat_to_mat(quat: np.ndarray) -> np.ndarray:
    """3x3 rotation matrix of a (w, x, y, z) quaternion."""
    r = np.zeros(9)
    mujoco.mju_quat2Mat(r, np.asarray(quat, dtype=float))
    return r.reshape(3, 3)


# -- compiled per-packet kernels (numba, cached on disk): at 2 kHz, Python and numpy per-call
# costs on 3-vectors were most of the kinematics' time --------------------------------------
_jit = numba.njit(cache=True, nogil=True)


@_jit
def _assemble(q: np.ndarray, v: np.ndarray, motor_pos: np.ndarray, motor_vel: np.ndarray,
              joint_pos: np.ndarray, joint_vel: np.ndarray, motor_q: np.ndarray,
              motor_d: np.ndarray, joint_q: np.ndarray, joint_d: np.ndarray,
              ach_q: np.ndarray, pla_q: np.ndarray, qpos: np.ndarray) -> None:
    """The measured joints into ``q``/``v`` (base at the origin, rods at zero), and ``qpos``."""
    v[:] = 0.0
    for i in range(motor_q.size):
        q[motor_q[i]] = motor_pos[i]
        v[motor_d[i]] = motor_vel[i]
    for i in range(joint_q.size):
        q[joint_q[i]] = joint_pos[i]
        v[joint_d[i]] = joint_vel[i]
    q[0:3] = 0.0
    q[3], q[4], q[5], q[6] = 1.0, 0.0, 0.0, 0.0
    for k in range(2):
        i = ach_q[k]
        q[i], q[i + 1], q[i + 2], q[i + 3] = 1.0, 0.0, 0.0, 0.0
        q[pla_q[k]] = 0.0
    qpos[:] = q


@_jit
def _solve_rods(xpos: np.ndarray, xmat: np.ndarray, q: np.ndarray, qpos: np.ndarray,
                rod_body: np.ndarray, tgt_body: np.ndarray, tgt_off: np.ndarray,
                ach_dir: np.ndarray, pla_axis: np.ndarray, pla_tip_proj: np.ndarray,
                ach_q: np.ndarray, pla_q: np.ndarray) -> None:
    """Closed-form rod angles so each rod tip meets its closure point (after pass 1).

    Rods 0-1 are the achilles rods (ball joint: the shortest rotation taking the tip
    direction onto the target direction), 2-3 the plantar rods (hinge: the signed angle
    between the two directions projected on the hinge plane). Writes ``q`` and ``qpos``.
    """
    for k in range(4):
        g = tgt_off[k]
        a, b, xr, r = xmat[tgt_body[k]], xpos[tgt_body[k]], xpos[rod_body[k]], xmat[rod_body[k]]
        # target point (world), minus the rod origin
        e0 = b[0] + a[0] * g[0] + a[1] * g[1] + a[2] * g[2] - xr[0]
        e1 = b[1] + a[3] * g[0] + a[4] * g[1] + a[5] * g[2] - xr[1]
        e2 = b[2] + a[6] * g[0] + a[7] * g[1] + a[8] * g[2] - xr[2]
        # u = R_rod^T e: the target in the rod's zero-angle frame
        u0 = r[0] * e0 + r[3] * e1 + r[6] * e2
        u1 = r[1] * e0 + r[4] * e1 + r[7] * e2
        u2 = r[2] * e0 + r[5] * e1 + r[8] * e2
        if k < 2:
            t0, t1, t2 = ach_dir[k, 0], ach_dir[k, 1], ach_dir[k, 2]
            n = math.sqrt(u0 * u0 + u1 * u1 + u2 * u2)
            u0, u1, u2 = u0 / n, u1 / n, u2 / n
            w = 1.0 + t0 * u0 + t1 * u1 + t2 * u2
            x = t1 * u2 - t2 * u1
            y = t2 * u0 - t0 * u2
            z = t0 * u1 - t1 * u0
            n = math.sqrt(w * w + x * x + y * y + z * z)
            i = ach_q[k]
            q[i], q[i + 1], q[i + 2], q[i + 3] = w / n, x / n, y / n, z / n
        else:
            a0, a1, a2 = pla_axis[k - 2, 0], pla_axis[k - 2, 1], pla_axis[k - 2, 2]
            p0, p1, p2 = pla_tip_proj[k - 2, 0], pla_tip_proj[k - 2, 1], pla_tip_proj[k - 2, 2]
            s = u0 * a0 + u1 * a1 + u2 * a2
            u0, u1, u2 = u0 - s * a0, u1 - s * a1, u2 - s * a2
            c0 = p1 * u2 - p2 * u1
            c1 = p2 * u0 - p0 * u2
            c2 = p0 * u1 - p1 * u0
            q[pla_q[k - 2]] = math.atan2(c0 * a0 + c1 * a1 + c2 * a2,
                                         p0 * u0 + p1 * u1 + p2 * u2)
    qpos[:] = q


@_jit
def _feet_and_springs(xpos: np.ndarray, xmat: np.ndarray, foot_body: np.ndarray,
                      foot_local: np.ndarray, foot_pos: np.ndarray, foot_axis: np.ndarray,
                      q: np.ndarray, spring_q: np.ndarray, spring_ref: np.ndarray,
                      spring_defl: np.ndarray) -> None:
    """Each foot's capsule centre and axis (pelvis frame), and the spring deflections."""
    for k in range(2):
        b = foot_body[k]
        r = xmat[b]
        for i in range(3):
            foot_pos[k, i] = xpos[b, i] + (r[3 * i] * foot_local[k, 0, 0]
                                           + r[3 * i + 1] * foot_local[k, 1, 0]
                                           + r[3 * i + 2] * foot_local[k, 2, 0])
            foot_axis[k, i] = (r[3 * i] * foot_local[k, 0, 1] + r[3 * i + 1] * foot_local[k, 1, 1]
                               + r[3 * i + 2] * foot_local[k, 2, 1])
        for j in range(2):
            spring_defl[k, j] = q[spring_q[k, j]] - spring_ref[k, j]


@_jit
def _foot_velocities(cvel: np.ndarray, subtree_com: np.ndarray, pelvis: int,
                     foot_body: np.ndarray, foot_pos: np.ndarray, foot_vel: np.ndarray) -> None:
    """Velocity of each foot's capsule centre relative to the pelvis (pelvis frame), from
    ``cvel`` with the base at rest: v + w x (p - c) at the tree's subtree CoM ``c``."""
    c0, c1, c2 = subtree_com[pelvis, 0], subtree_com[pelvis, 1], subtree_com[pelvis, 2]
    for k in range(2):
        w = cvel[foot_body[k]]
        e0, e1, e2 = foot_pos[k, 0] - c0, foot_pos[k, 1] - c1, foot_pos[k, 2] - c2
        foot_vel[k, 0] = w[3] + w[1] * e2 - w[2] * e1
        foot_vel[k, 1] = w[4] + w[2] * e0 - w[0] * e2
        foot_vel[k, 2] = w[5] + w[0] * e1 - w[1] * e0


@_jit
def _rod_velocities(xpos: np.ndarray, xmat: np.ndarray, cvel: np.ndarray,
                    subtree_com: np.ndarray, v: np.ndarray, pelvis: int, rod_body: np.ndarray,
                    tgt_body: np.ndarray, rod_tip: np.ndarray, tgt_off: np.ndarray,
                    pla_axis: np.ndarray, ach_d: np.ndarray, pla_d: np.ndarray) -> None:
    """Rod joint rates that keep the closures' relative velocity zero (min-norm for the
    achilles ball joint, whose spin about its own axis is not constrained).

    With the rod rates zero in ``cvel``, each tip moves rigidly with its parent; the rate
    must make up the difference ``dv`` to the target's velocity: for the ball joint
    ``w = r x dv / |r|^2`` (given to MuJoCo in the rod frame), for the hinge about ``a``
    ``qdot = (a x r).dv / |a x r|^2``.
    """
    c0, c1, c2 = subtree_com[pelvis, 0], subtree_com[pelvis, 1], subtree_com[pelvis, 2]
    for k in range(4):
        # tip offset r from the rod origin and target offset g from its body, world
        m, t = xmat[rod_body[k]], rod_tip[k]
        r0 = m[0] * t[0] + m[1] * t[1] + m[2] * t[2]
        r1 = m[3] * t[0] + m[4] * t[1] + m[5] * t[2]
        r2 = m[6] * t[0] + m[7] * t[1] + m[8] * t[2]
        a, g = xmat[tgt_body[k]], tgt_off[k]
        g0 = a[0] * g[0] + a[1] * g[1] + a[2] * g[2]
        g1 = a[3] * g[0] + a[4] * g[1] + a[5] * g[2]
        g2 = a[6] * g[0] + a[7] * g[1] + a[8] * g[2]
        # point velocities from cvel (rotation; linear at the subtree CoM): v + w x (p - c)
        w, p = cvel[rod_body[k]], xpos[rod_body[k]]
        e0, e1, e2 = p[0] + r0 - c0, p[1] + r1 - c1, p[2] + r2 - c2
        v0 = w[3] + w[1] * e2 - w[2] * e1
        v1 = w[4] + w[2] * e0 - w[0] * e2
        v2 = w[5] + w[0] * e1 - w[1] * e0
        w, p = cvel[tgt_body[k]], xpos[tgt_body[k]]
        e0, e1, e2 = p[0] + g0 - c0, p[1] + g1 - c1, p[2] + g2 - c2
        d0 = w[3] + w[1] * e2 - w[2] * e1 - v0
        d1 = w[4] + w[2] * e0 - w[0] * e2 - v1
        d2 = w[5] + w[0] * e1 - w[1] * e0 - v2
        if k < 2:
            n = r0 * r0 + r1 * r1 + r2 * r2
            w0 = (r1 * d2 - r2 * d1) / n
            w1 = (r2 * d0 - r0 * d2) / n
            w2 = (r0 * d1 - r1 * d0) / n
            i = ach_d[k]
            v[i] = m[0] * w0 + m[3] * w1 + m[6] * w2
            v[i + 1] = m[1] * w0 + m[4] * w1 + m[7] * w2
            v[i + 2] = m[2] * w0 + m[5] * w1 + m[8] * w2
        else:
            x0, x1, x2 = pla_axis[k - 2, 0], pla_axis[k - 2, 1], pla_axis[k - 2, 2]
            a0 = m[0] * x0 + m[1] * x1 + m[2] * x2
            a1 = m[3] * x0 + m[4] * x1 + m[5] * x2
            a2 = m[6] * x0 + m[7] * x1 + m[8] * x2
            n0 = a1 * r2 - a2 * r1
            n1 = a2 * r0 - a0 * r2
            n2 = a0 * r1 - a1 * r0
            v[pla_d[k - 2]] = (n0 * d0 + n1 * d1 + n2 * d2) / (n0 * n0 + n1 * n1 + n2 * n2)


class LegKinematics:
    """Measured joints -> full ``q``/``v`` (rods solved), foot points, spring loads, CoM, momentum.

    Call ``update`` once per packet, then read the attributes (all in the pelvis frame):

    * ``q`` (nq), ``v`` (nv): MuJoCo-order coordinates with the base at the origin; the caller
      overwrites the base part with its estimate before publishing.
    * ``foot_pos`` (2, 3): the centre of each foot's collision capsule (mid-foot, ``radius``
      above the sole) relative to the pelvis origin; ``foot_axis`` (2, 3) its unit axis (heel
      to toe or back), for picking the sole point that touches the ground.
    * ``foot_vel`` (2, 3): the capsule centres' velocity relative to the pelvis.
    * ``spring_defl`` (2, 2): (shin, heel) spring deflections per leg, rad.
    * ``com`` (3), ``com_vel`` (3), ``angmom_com`` (3) after ``update_momentum``.
    """

    def __init__(self, model: mujoco.MjModel | None = None) -> None:
        m = model if model is not None else load_model()
        self.m = m
        self.d = d = mujoco.MjData(m)
        self.nq, self.nv = int(m.nq), int(m.nv)
        self.mass = float(m.body_subtreemass[1])

        def jid(name: str) -> int:
            j = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, name)
            if j < 0:
                raise RuntimeError(f"Cassie model has no joint {name!r}")
            return j

        def bid(name: str) -> int:
            b = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, name)
            if b < 0:
                raise RuntimeError(f"Cassie model has no body {name!r}")
            return b

        mj = [jid(n) for n in MOTOR_NAMES]
        pj = [jid(n) for n in JOINT_NAMES]
        self.motor_qpos = m.jnt_qposadr[mj].astype(np.intp)
        self.motor_dof = m.jnt_dofadr[mj].astype(np.intp)
        self.joint_qpos = m.jnt_qposadr[pj].astype(np.intp)
        self.joint_dof = m.jnt_dofadr[pj].astype(np.intp)
        self.pelvis = bid("cassie-pelvis")

        # -- rod closures: achilles (ball) and plantar (hinge) per side --------------------
        def qadr(name: str) -> int:
            return int(m.jnt_qposadr[jid(name)])

        def dadr(name: str) -> int:
            return int(m.jnt_dofadr[jid(name)])

        self._ach_qpos = np.array([qadr(f"{s}-achilles-rod") for s in SIDES], dtype=np.intp)
        self._ach_dof = np.array([dadr(f"{s}-achilles-rod") for s in SIDES], dtype=np.intp)
        self._pla_qpos = np.array([qadr(f"{s}-plantar-rod") for s in SIDES], dtype=np.intp)
        self._pla_dof = np.array([dadr(f"{s}-plantar-rod") for s in SIDES], dtype=np.intp)
        self._ach_body = np.array([bid(f"{s}-achilles-rod") for s in SIDES])
        self._pla_body = np.array([bid(f"{s}-plantar-rod") for s in SIDES])
        self._pla_axis = np.array([m.jnt_axis[jid(f"{s}-plantar-rod")] for s in SIDES])
        # connect equalities: rod tip (on the rod body) must meet a point on the other body
        ach_tip = np.zeros((2, 3))
        ach_tgt_body = np.zeros(2, dtype=np.intp)
        ach_tgt = np.zeros((2, 3))
        pla_tip = np.zeros((2, 3))
        pla_tgt_body = np.zeros(2, dtype=np.intp)
        pla_tgt = np.zeros((2, 3))
        for i in range(m.neq):
            if m.eq_type[i] != mujoco.mjtEq.mjEQ_CONNECT:
                continue
            b1, b2 = int(m.eq_obj1id[i]), int(m.eq_obj2id[i])
            for k in range(2):
                tip, off = m.eq_data[i, 0:3], m.eq_data[i, 3:6]
                if b1 == self._ach_body[k]:
                    ach_tip[k], ach_tgt_body[k], ach_tgt[k] = tip, b2, off
                elif b1 == self._pla_body[k]:
                    pla_tip[k], pla_tgt_body[k], pla_tgt[k] = tip, b2, off
        if not (ach_tip[:, 0].all() and pla_tip[:, 0].all()):
            raise RuntimeError("Cassie model: rod closures not found where expected")
        for k in range(2):
            if np.any(m.jnt_pos[jid(f"{SIDES[k]}-plantar-rod")]) or np.any(
                m.jnt_pos[jid(f"{SIDES[k]}-achilles-rod")]
            ):
                raise RuntimeError("Cassie model: rod joints are expected at their body origins")
        self._ach_tip, self._ach_tgt_body, self._ach_tgt = ach_tip, ach_tgt_body, ach_tgt
        self._pla_tip, self._pla_tgt_body, self._pla_tgt = pla_tip, pla_tgt_body, pla_tgt
        # vectorised tables, rows: left achilles, right achilles, left plantar, right plantar
        self._rod_body = np.concatenate([self._ach_body, self._pla_body]).astype(np.intp)
        self._tgt_body = np.concatenate([ach_tgt_body, pla_tgt_body]).astype(np.intp)
        self._rod_tip = np.concatenate([ach_tip, pla_tip])
        self._tgt_off = np.concatenate([ach_tgt, pla_tgt])
        self._ach_dir = ach_tip / np.linalg.norm(ach_tip, axis=1)[:, None]
        ax = self._pla_axis / np.linalg.norm(self._pla_axis, axis=1)[:, None]
        self._pla_axis = ax
        self._pla_tip_proj = pla_tip - np.einsum("ij,ij->i", pla_tip, ax)[:, None] * ax
        # -- feet: collision capsule centre as the contact reference point -----------------
        self.foot_body = np.array([bid(f"{s}-foot") for s in SIDES], dtype=np.intp)
        geoms = [
            int(np.flatnonzero((m.geom_bodyid == b) & (m.geom_contype != 0))[0])
            for b in self.foot_body
        ]
        self.foot_geom = np.array(geoms, dtype=np.intp)
        self.foot_offset = m.geom_pos[geoms].copy()  # capsule centre in the foot body frame
        # the capsule's axis (its local z) in the foot body frame
        self._foot_axis_local = np.array(
            [_quat_to_mat(m.geom_quat[g])[:, 2] for g in geoms]
        )
        # per foot, columns: capsule centre and capsule axis, in the foot body frame
        self._foot_local = np.stack([self.foot_offset, self._foot_axis_local], axis=2)
        self._foot_out = np.zeros((2, 3, 2))
        self.foot_radius = float(m.geom_size[geoms[0], 0])
        self.foot_half_length = float(m.geom_size[geoms[0], 1])

        # -- springs --------------------------------------------------------------------------
        sj = [[jid(f"{s}-{n}") for n in SPRING_JOINTS] for s in SIDES]
        self.spring_qpos = np.array([[m.jnt_qposadr[j] for j in row] for row in sj])
        self.spring_dof = np.array([[m.jnt_dofadr[j] for j in row] for row in sj])
        self.spring_k = np.array([[m.jnt_stiffness[j] for j in row] for row in sj])
        self.spring_ref = np.array([[m.qpos_spring[m.jnt_qposadr[j]] for j in row] for row in sj])

        # -- outputs and scratch (preallocated) ---------------------------------------------
        self.q = m.qpos0.copy()
        self.q[0:7] = (0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0)
        self.v = np.zeros(self.nv)
        self.foot_pos = np.zeros((2, 3))
        self.foot_axis = np.zeros((2, 3))
        self.foot_vel = np.zeros((2, 3))
        self.spring_defl = np.zeros((2, 2))
        self.com = np.zeros(3)
        self.com_vel = np.zeros(3)
        self.angmom_com = np.zeros(3)
        # views of the private MjData's arrays the kernels read and write (fetching an MjData
        # attribute builds a new view each time)
        self._qpos, self._qvel = d.qpos, d.qvel
        self._xpos, self._xmat, self._cvel = d.xpos, d.xmat, d.cvel
        self._subtree_com = d.subtree_com
        self.spring_qpos = self.spring_qpos.astype(np.intp)
        self.spring_ref = np.ascontiguousarray(self.spring_ref, dtype=float)
        # compile (or load from the on-disk cache) the kernels now, not on the first packet
        z10, z8 = np.zeros(len(MOTOR_NAMES)), np.zeros(len(JOINT_NAMES))
        self.update(z10, z10, z8, z8)

    # -- per-packet -------------------------------------------------------------------------
    def update(
        self,
        motor_pos: np.ndarray,
        motor_vel: np.ndarray,
        joint_pos: np.ndarray,
        joint_vel: np.ndarray,
    ) -> None:
        """Joint coordinates from one packet: solve rods, feet, springs (pelvis frame)."""
        m, d, q, v = self.m, self.d, self.q, self.v
        _assemble(q, v, motor_pos, motor_vel, joint_pos, joint_vel, self.motor_qpos,
                  self.motor_dof, self.joint_qpos, self.joint_dof, self._ach_qpos,
                  self._pla_qpos, self._qpos)
        # pass 1: rods at their zero angle, to find where their tips must go
        mujoco.mj_kinematics(m, d)
        _solve_rods(self._xpos, self._xmat, q, self._qpos, self._rod_body, self._tgt_body,
                    self._tgt_off, self._ach_dir, self._pla_axis, self._pla_tip_proj,
                    self._ach_qpos, self._pla_qpos)
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        _feet_and_springs(self._xpos, self._xmat, self.foot_body, self._foot_local,
                          self.foot_pos, self.foot_axis, q, self.spring_qpos, self.spring_ref,
                          self.spring_defl)
        # rod velocities from the closures
        self._qvel[:] = v
        mujoco.mj_comVel(m, d)
        _foot_velocities(self._cvel, self._subtree_com, self.pelvis, self.foot_body,
                         self.foot_pos, self.foot_vel)
        _rod_velocities(self._xpos, self._xmat, self._cvel, self._subtree_com, v,
                        self.pelvis, self._rod_body, self._tgt_body, self._rod_tip,
                        self._tgt_off, self._pla_axis, self._ach_dof, self._pla_dof)

    def update_momentum(self, v_base_lin: np.ndarray, w_base: np.ndarray) -> None:
        """CoM, CoM velocity and angular momentum about the CoM, pelvis frame, with the base
        moving at ``v_base_lin`` (pelvis frame) and ``w_base`` (pelvis frame). Call after
        ``update``; also rewrites ``v[0:6]``."""
        m, d, v = self.m, self.d, self.v
        v[0:3] = v_base_lin
        v[3:6] = w_base
        d.qvel[:] = v
        mujoco.mj_comVel(m, d)
        mujoco.mj_subtreeVel(m, d)
        b = self.pelvis
        self.com[:] = d.subtree_com[b]
        self.com_vel[:] = d.subtree_linvel[b]
        self.angmom_com[:] = d.subtree_angmom[b]

    def closure_residual(self) -> np.ndarray:
        """Distance (m) between each rod tip and its target after ``update`` (test helper)."""
        d = self.d
        out = []
        for tips, tgts, rb, tb in (
            (self._ach_tip, self._ach_tgt, self._ach_body, self._ach_tgt_body),
            (self._pla_tip, self._pla_tgt, self._pla_body, self._pla_tgt_body),
        ):
            for k in range(2):
                p1 = d.xpos[rb[k]] + d.xmat[rb[k]].reshape(3, 3) @ tips[k]
                p2 = d.xpos[tb[k]] + d.xmat[tb[k]].reshape(3, 3) @ tgts[k]
                out.append(float(np.linalg.norm(p1 - p2)))
        return np.array(out)
