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

import mujoco
import numpy as np

from runtime.cassie_packets import JOINT_NAMES, MOTOR_NAMES
from runtime.robot import SIDES, SPRING_JOINTS, load_model

from .kernels import (
    _assemble,
    _feet_and_springs,
    _foot_velocities,
    _rod_velocities,
    _solve_rods,
)


def _quat_to_mat(quat: np.ndarray) -> np.ndarray:
    """3x3 rotation matrix of a (w, x, y, z) quaternion."""
    r = np.zeros(9)
    mujoco.mju_quat2Mat(r, np.asarray(quat, dtype=float))
    return r.reshape(3, 3)


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
