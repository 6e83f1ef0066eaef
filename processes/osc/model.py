"""Controller-side Cassie model: kinematics and dynamics terms the OSC QP (14) is built from.

The controller owns its own ``MjModel``/``MjData`` (never the simulator's). Contacts, equality
constraints and joint limits are disabled in this copy: the OSC imposes the loop closures and the
rigid leaf springs itself as the 14 holonomic rows of (14c), and the foot contacts as (14d).
All buffers are allocated once in ``__init__``; ``update`` only writes into them.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import mujoco
import numpy as np

#: Foot blade contact points in the foot body frame: the two ends of the collision capsule
#: (menagerie cassie.xml), ordered (front, rear): at the standing pose world x is +0.06, -0.10 m.
FOOT_CAPSULE_ENDS = np.array([[-0.052821, 0.092622, 0.0], [0.069746, -0.010224, 0.0]])
FOOT_CAPSULE_RADIUS = 0.02

LEFT, RIGHT = 0, 1
SIDES = ("left", "right")
MOTOR_JOINTS = ("hip-roll", "hip-yaw", "hip-pitch", "knee", "foot")
SPRING_JOINTS = ("shin", "heel-spring")


def load_cassie() -> mujoco.MjModel:
    """Load the menagerie Cassie scene. Offline it needs ``MENAGERIE_ROOT``; when unset, a
    ``shared/menagerie`` folder beside the checkout is used if there is one."""
    if not os.environ.get("MENAGERIE_ROOT"):
        shared = Path(__file__).resolve().parents[3] / "shared" / "menagerie"
        if shared.is_dir():
            os.environ["MENAGERIE_ROOT"] = str(shared)
    import mujoco_menagerie

    return mujoco_menagerie.load("agility_cassie")


class CassieModel:
    """Kinematics, dynamics and constraint terms of Cassie at one state, recomputed per tick.

    After ``update(q, v)`` the public arrays hold, for the current state:
    ``Jh``/``Jh_dot_v`` (14 holonomic rows: 2x3 achilles rods, 2x2 in-plane plantar rod rows,
    4 rigid springs), ``Jc``/``Jc_dot_v`` (4 foot points x 3, world frame), ``p_contact``,
    ``com``/``com_vel``/``J_com``/``com_dot_v``, and ``h`` = bias - passive forces so that the
    dynamics (13)/(14b) read ``M dv + h = B u + Jh^T lh + Jc^T lc``.
    """

    n_holonomic = 14
    n_contact_points = 4

    def __init__(self, model: mujoco.MjModel | None = None) -> None:
        src = model if model is not None else load_cassie()
        # Own copy: the controller must never share MjData/MjModel with the simulator.
        self.m = _copy_model(src)
        m = self.m
        m.opt.disableflags |= int(
            mujoco.mjtDisableBit.mjDSBL_CONTACT
            | mujoco.mjtDisableBit.mjDSBL_CONSTRAINT
            | mujoco.mjtDisableBit.mjDSBL_LIMIT
        )
        self.d = mujoco.MjData(m)
        nv = m.nv
        self.nv, self.nq, self.nu = nv, m.nq, m.nu

        jid = {m.joint(i).name: i for i in range(m.njnt)}
        self.motor_dof = np.array([m.jnt_dofadr[j] for j in m.actuator_trnid[:, 0]], dtype=int)
        self.motor_qpos = np.array([m.jnt_qposadr[j] for j in m.actuator_trnid[:, 0]], dtype=int)
        gear = m.actuator_gear[:, 0]
        #: joint-side torque limits (N m): ctrlrange x gear; the foot's 45 N m is the tight one
        self.u_max = np.abs(m.actuator_ctrlrange[:, 1]) * gear
        self.gear = gear.copy()
        # B of (13): joint-side torques u (actuator order) act one-to-one on their joint dofs.
        self.B = np.zeros((nv, m.nu))
        self.B[self.motor_dof, np.arange(m.nu)] = 1.0

        self.spring_dof = np.array(
            [m.jnt_dofadr[jid[f"{s}-{j}"]] for s in SIDES for j in SPRING_JOINTS], dtype=int
        )
        self.spring_qpos = np.array(
            [m.jnt_qposadr[jid[f"{s}-{j}"]] for s in SIDES for j in SPRING_JOINTS], dtype=int
        )
        self.foot_body = np.array([m.body(f"{s}-foot").id for s in SIDES], dtype=int)
        self.foot_joint_axis_jnt = np.array([jid[f"{s}-foot"] for s in SIDES], dtype=int)
        self.pelvis_body = m.body("cassie-pelvis").id
        self.hip_yaw_qpos = np.array([m.jnt_qposadr[jid[f"{s}-hip-yaw"]] for s in SIDES])
        self.hip_yaw_dof = np.array([m.jnt_dofadr[jid[f"{s}-hip-yaw"]] for s in SIDES])
        self.foot_qpos = np.array([m.jnt_qposadr[jid[f"{s}-foot"]] for s in SIDES])
        self.foot_dof = np.array([m.jnt_dofadr[jid[f"{s}-foot"]] for s in SIDES])
        self.mass = float(m.body_subtreemass[self.pelvis_body])
        #: gravity magnitude: RNE seeds the world body with -gravity, removed from the CoM term
        self._g = -float(m.opt.gravity[2])

        # Loop closures: the four `connect` equalities (body1 anchor, body2 anchor).
        self.eq_b1 = m.eq_obj1id.copy()
        self.eq_b2 = m.eq_obj2id.copy()
        self.eq_a1 = m.eq_data[:, 0:3].copy()
        self.eq_a2 = m.eq_data[:, 3:6].copy()
        names = [m.body(b).name for b in self.eq_b1]
        #: plantar rods close a planar four-bar: only the two in-plane rows are independent
        self.eq_planar = np.array(["plantar" in n for n in names])

        # Preallocated per-tick outputs.
        self.h = np.zeros(nv)
        self.Jh = np.zeros((self.n_holonomic, nv))
        self.Jh_dot_v = np.zeros(self.n_holonomic)
        self.Jc = np.zeros((3 * self.n_contact_points, nv))
        self.Jc_dot_v = np.zeros(3 * self.n_contact_points)
        self.p_contact = np.zeros((self.n_contact_points, 3))
        self.v_contact = np.zeros((self.n_contact_points, 3))
        self.J_com = np.zeros((3, nv))
        self.com = np.zeros(3)
        self.com_vel = np.zeros(3)
        self.com_dot_v = np.zeros(3)
        self.R_pelvis = np.eye(3)
        self.R_list: list[list[float]] = self.R_pelvis.tolist()
        self.foot_axis = np.zeros((2, 3))
        self._pts = np.zeros((2 * len(self.eq_b1) + self.n_contact_points, 3))
        self._pt_body = np.zeros(len(self._pts), dtype=int)
        self._pt_body[: len(self.eq_b1)] = self.eq_b1
        self._pt_body[len(self.eq_b1) : 2 * len(self.eq_b1)] = self.eq_b2
        self._pt_body[2 * len(self.eq_b1) :] = np.repeat(self.foot_body, 2)
        ne = len(self.eq_b1)
        self._nrod = 2 * ne
        self._pt_local = np.zeros((len(self._pts), 3))
        self._pt_local[:ne] = self.eq_a1
        self._pt_local[ne : 2 * ne] = self.eq_a2
        self._pt_local[2 * ne :] = np.tile(FOOT_CAPSULE_ENDS, (2, 1))
        self._tmp31 = np.zeros((len(self._pts), 3, 1))
        self._Jpts = np.zeros((len(self._pts), 3, nv))
        self._Jdots = np.zeros((len(self._pts), 3, nv))
        self._Jdots_flat = self._Jdots.reshape(-1, nv)
        # per-point (body, J view, Jdot view, point view): no indexing in the hot loop
        self._pt_views = [(int(self._pt_body[i]), self._Jpts[i], self._Jdots[i], self._pts[i])
                          for i in range(len(self._pts))]
        # MjData arrays are views into buffers that never move: fetch the wrappers once
        self._arr = _DataViews(self.d)
        #: (3, 12) averaging of a foot's two contact points: foot-centre rows from Jc, p, v
        self.foot_avg = np.zeros((2, 3, 3 * self.n_contact_points))
        for side in range(2):
            for e in range(2):
                self.foot_avg[side, :, 6 * side + 3 * e : 6 * side + 3 * e + 3] = 0.5 * np.eye(3)
        self.p_contact_l: list[list[float]] = [[0.0] * 3 for _ in range(4)]
        self.v_contact_l: list[list[float]] = [[0.0] * 3 for _ in range(4)]
        self.Jc_dot_v_l: list[float] = [0.0] * 12
        self.com_l = [0.0] * 3
        self.com_vel_l = [0.0] * 3
        self.com_dot_v_l = [0.0] * 3
        self.rod_residual = np.zeros((ne, 3))
        # Jh row layout: [plantar rods 2 x 2 in-plane rows | achilles rods 2 x 3 | springs 4]
        self._planar_k = np.flatnonzero(self.eq_planar)
        self._achilles_k = np.flatnonzero(~self.eq_planar)
        self._planar_b2 = self.eq_b2[self._planar_k]
        self._Jh_planar = self.Jh[0:4].reshape(2, 2, nv)  # views: matmul writes into Jh
        self._jdv_planar = self.Jh_dot_v[0:4].reshape(2, 2, 1)
        for k, dof in enumerate(self.spring_dof):
            self.Jh[10 + k, dof] = 1.0  # rigid springs (14c): dv_spring = 0, Jdot = 0

    # ------------------------------------------------------------------ per tick
    def update(self, q: np.ndarray, v: np.ndarray) -> None:
        """Recompute every term for state (q, v): kinematics, M factor, h, Jacobians, Jdot v."""
        m, d, a = self.m, self.d, self._arr
        a.qpos[:] = q
        a.qvel[:] = v
        mujoco.mj_fwdPosition(m, d)  # kinematics, CoM, M and its factorization
        mujoco.mj_fwdVelocity(m, d)  # qfrc_bias, qfrc_passive (springs, damping), cvel, cdof_dot
        np.subtract(a.qfrc_bias, a.qfrc_passive, out=self.h)
        # RNE with qacc = 0: the CoM bias acceleration comes from the pelvis subtree's cfrc_int.
        a.qacc[:] = 0.0
        mujoco.mj_rnePostConstraint(m, d)
        self.R_list = a.xmat[self.pelvis_body].reshape(3, 3).tolist()
        self.R_pelvis[:] = self.R_list
        self.foot_axis[:] = a.xaxis[self.foot_joint_axis_jnt]

        # Points: rod anchors on body1, on body2, then foot contact points (all vectorized).
        pb = self._pt_body
        pts = self._pts
        np.matmul(a.xmat[pb].reshape(-1, 3, 3), self._pt_local[:, :, None], out=self._tmp31)
        np.add(self._tmp31[:, :, 0], a.xpos[pb], out=pts)
        pts[self._nrod :, 2] -= FOOT_CAPSULE_RADIUS  # the capsule's lowest point on flat ground
        npt = len(pts)
        Jp = self._Jpts
        for b, jp, jd, p in self._pt_views:
            mujoco.mj_jac(m, d, jp, None, p, b)
            mujoco.mj_jacDot(m, d, jd, None, p, b)
        acc = (self._Jdots_flat @ v).reshape(npt, 3)  # Jdot v of every point

        # Holonomic rows (14c): connect residual p1 - p2; planar rods keep 2 in-plane rows.
        ne = len(self.eq_b1)
        Jr = Jp[:ne] - Jp[ne : 2 * ne]
        ar = acc[:ne] - acc[ne : 2 * ne]
        self.rod_residual[:] = pts[:ne] - pts[ne : 2 * ne]
        # Rows 0-3: the two plantar four-bars. Their plane is the foot's local x-y plane (all
        # their hinges turn about local z), so the in-plane rows are the foot's x and y axes
        # in the world, E. Row derivative: d/dt(E J_r) v = E Jdot_r v + Edot J_r v with
        # Edot = -E [w]x for the foot's world angular velocity w (the second term vanishes
        # when v satisfies the closure, but keeps (14c) exact for any v).
        kp, ka = self._planar_k, self._achilles_k
        E = a.xmat[self._planar_b2].reshape(-1, 3, 3).transpose(0, 2, 1)[:, 0:2, :]
        JrP = Jr[kp]
        np.matmul(E, JrP, out=self._Jh_planar)
        rd = JrP @ v  # relative anchor velocities (2, 3)
        w = a.cvel[self._planar_b2, 0:3]
        wxr = w[:, _I1] * rd[:, _I2] - w[:, _I2] * rd[:, _I1]
        np.matmul(E, (ar[kp] - wxr)[:, :, None], out=self._jdv_planar)
        # Rows 4-9: the achilles rods (ball joints): all three rows of the connect residual.
        self.Jh[4:10] = Jr[ka].reshape(6, -1)
        self.Jh_dot_v[4:10] = ar[ka].reshape(6)
        # rows 10..13 are the rigid springs (constant, set in __init__); their Jdot v is 0

        # Contact points (14d), world frame.
        self.Jc[:] = Jp[2 * ne :].reshape(-1, self.nv)
        self.Jc_dot_v[:] = acc[2 * ne :].reshape(-1)
        self.p_contact[:] = pts[2 * ne :]
        np.dot(self.Jc, v, out=self.v_contact.reshape(-1))

        # Centre of mass.
        self.com[:] = a.subtree_com[self.pelvis_body]
        mujoco.mj_jacSubtreeCom(m, d, self.J_com, self.pelvis_body)
        np.dot(self.J_com, v, out=self.com_vel)
        # With qacc = 0 the pelvis subtree's net force (linear part of cfrc_int) is M (Jdot v)_com
        # plus M g (MuJoCo's gravity seed), so the CoM bias acceleration needs no body loop.
        np.multiply(a.cfrc_int[self.pelvis_body, 3:6], 1.0 / self.mass, out=self.com_dot_v)
        self.com_dot_v[2] -= self._g
        # float copies for the tasks' 3-vector arithmetic (cheaper than numpy calls)
        self.p_contact_l = self.p_contact.tolist()
        self.v_contact_l = self.v_contact.tolist()
        self.Jc_dot_v_l = self.Jc_dot_v.tolist()
        self.com_l = self.com.tolist()
        self.com_vel_l = self.com_vel.tolist()
        self.com_dot_v_l = self.com_dot_v.tolist()

    def solve_M(self, out: np.ndarray, rhs: np.ndarray) -> None:
        """``out = M^-1 rhs`` for row-stacked right-hand sides (k, nv), with MuJoCo's factor."""
        mujoco.mj_solveM(self.m, self.d, out, rhs)

    # ------------------------------------------------------------------ helpers
    def foot_pitch(self, side: int) -> float:
        """World pitch of a foot blade (rad, positive toe up), from its two contact points."""
        f, r = self.p_contact_l[2 * side], self.p_contact_l[2 * side + 1]  # front, rear
        return math.atan2(f[2] - r[2], math.hypot(f[0] - r[0], f[1] - r[1]))

    def foot_center(self, side: int) -> np.ndarray:
        """Midpoint of a foot's two contact points (world): the swing-foot task point."""
        return 0.5 * (self.p_contact[2 * side] + self.p_contact[2 * side + 1])

    def pelvis_yaw(self) -> float:
        """Yaw of the pelvis x axis in the world (rad)."""
        return math.atan2(self.R_list[1][0], self.R_list[0][0])


_I1 = np.array([1, 2, 0])
_I2 = np.array([2, 0, 1])


class _DataViews:
    """Cached numpy views of the MjData fields used per tick (each attribute access on
    MjData builds a new wrapper, which costs more than the small operations done on it)."""

    def __init__(self, d: mujoco.MjData) -> None:
        self.qpos = d.qpos
        self.qvel = d.qvel
        self.qacc = d.qacc
        self.qfrc_bias = d.qfrc_bias
        self.qfrc_passive = d.qfrc_passive
        self.xmat = d.xmat
        self.xpos = d.xpos
        self.xaxis = d.xaxis
        self.subtree_com = d.subtree_com
        self.cfrc_int = d.cfrc_int
        self.cvel = d.cvel


def _copy_model(src: mujoco.MjModel) -> mujoco.MjModel:
    """A deep copy of an MjModel (the controller must not alias the simulator's options)."""
    import copy

    return copy.deepcopy(src)


# ---------------------------------------------------------------------- standing pose
def standing_pose(
    model: mujoco.MjModel | None = None, pelvis_height: float = 0.95, iters: int = 60
) -> np.ndarray:
    """Solve an inverse-kinematics standing pose: closed rods, unloaded springs, feet flat.

    Starts from the ``home`` keyframe and runs damped Gauss-Newton on: rod closures, spring
    deflections (zero), both foot blades on z = 0, hip roll/yaw at zero, feet centred under
    the CoM in x; the pelvis is placed at ``pelvis_height`` with identity orientation.
    """
    cm = CassieModel(model)
    m, d = cm.m, cm.d
    q = m.key_qpos[0].copy()
    q[0:3] = (0.0, 0.0, pelvis_height)
    q[3:7] = (1.0, 0.0, 0.0, 0.0)
    v0 = np.zeros(m.nv)
    jid = {m.joint(i).name: i for i in range(m.njnt)}
    hip_fix = [jid[f"{s}-hip-{j}"] for s in SIDES for j in ("roll", "yaw")]
    for _ in range(iters):
        cm.update(q, v0)
        rows, res = [], []
        # rod closures and springs (reuse the holonomic rows)
        for k in cm._planar_k:  # same row order as Jh
            res.append(d.xmat[cm.eq_b2[k]].reshape(3, 3).T[0:2] @ cm.rod_residual[k])
        for k in cm._achilles_k:
            res.append(cm.rod_residual[k])
        rows.append(cm.Jh[:10])
        res.append(q[cm.spring_qpos])
        rows.append(cm.Jh[10:])
        # feet on the ground
        res.append(cm.p_contact[:, 2])
        rows.append(cm.Jc[2::3])
        # hip roll / yaw at zero
        for j in hip_fix:
            row = np.zeros((1, m.nv))
            row[0, m.jnt_dofadr[j]] = 1.0
            rows.append(row)
            res.append(np.array([q[m.jnt_qposadr[j]]]))
        # feet centred under the CoM in x, and symmetric
        res.append(np.array([cm.p_contact[:, 0].mean() - cm.com[0]]))
        rows.append((cm.Jc[0::3].mean(axis=0) - cm.J_com[0])[None])
        J = np.vstack(rows)
        r = np.concatenate(res)
        J[:, :6] = 0.0  # the base is fixed
        dq = -np.linalg.solve(J.T @ J + 1e-6 * np.eye(m.nv), J.T @ r)
        mujoco.mj_integratePos(m, q, dq, 1.0)
        if np.linalg.norm(r) < 1e-10:
            break
    return q
