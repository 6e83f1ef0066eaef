"""Controller-side Cassie model: kinematics and dynamics terms the OSC QP (14) is built from.

The controller owns its own ``MjModel``/``MjData`` (never the simulator's). Contacts, equality
constraints and joint limits are disabled in this copy: the OSC imposes the loop closures and the
rigid leaf springs itself as the 14 holonomic rows of (14c), and the foot contacts as (14d).
All buffers are allocated once in ``__init__``; ``update`` only writes into them: after the
MuJoCo passes, one compiled kernel (numba, cached on disk) computes every point, Jacobian and
``Jdot v`` term from MuJoCo's ``cdof``/``cdof_dot``/``cvel`` the way ``mj_jac``/``mj_jacDot``/
``mj_jacSubtreeCom`` do (24 + 1 MuJoCo calls and ~30 numpy calls per tick before).
"""

from __future__ import annotations

import math

import mujoco
import numba
import numpy as np

from runtime.robot import (
    FOOT_BLADE_ENDS,
    FOOT_BLADE_RADIUS,
    SIDES,
    SPRING_JOINTS,
    load_model,
)

#: Foot blade contact points in the foot body frame (front, rear), as arrays
FOOT_CAPSULE_ENDS = np.array(FOOT_BLADE_ENDS)
FOOT_CAPSULE_RADIUS = FOOT_BLADE_RADIUS

LEFT, RIGHT = 0, 1
MOTOR_JOINTS = ("hip-roll", "hip-yaw", "hip-pitch", "knee", "foot")
#: (the one loader of the model: runtime.robot)
load_cassie = load_model


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
        self.hip_yaw_qpos = np.array([m.jnt_qposadr[jid[f"{s}-hip-yaw"]] for s in SIDES],
                                     dtype=np.int64)
        self.hip_yaw_dof = np.array([m.jnt_dofadr[jid[f"{s}-hip-yaw"]] for s in SIDES],
                                    dtype=np.int64)
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
        self.J_com = np.zeros((3, nv))
        ne = len(self.eq_b1)
        npt = 2 * ne + self.n_contact_points
        # Points: rod anchors on body1 (ne), on body2 (ne), then the 4 foot contact points.
        self._pt_body = np.zeros(npt, dtype=np.int64)
        self._pt_body[:ne] = self.eq_b1
        self._pt_body[ne : 2 * ne] = self.eq_b2
        self._pt_body[2 * ne :] = np.repeat(self.foot_body, 2)
        self._pt_local = np.zeros((npt, 3))
        self._pt_local[:ne] = self.eq_a1
        self._pt_local[ne : 2 * ne] = self.eq_a2
        self._pt_local[2 * ne :] = np.tile(FOOT_CAPSULE_ENDS, (2, 1))
        self._nrod = 2 * ne
        # Jh row layout: [plantar rods 2 x 2 in-plane rows | achilles rods 2 x 3 | springs 4]
        self._planar_k = np.flatnonzero(self.eq_planar)
        self._achilles_k = np.flatnonzero(~self.eq_planar)
        self._planar_b2 = self.eq_b2[self._planar_k]
        if len(self._planar_k) != 2 or len(self._achilles_k) != 2:
            raise ValueError("expected two plantar and two achilles rod closures")
        for k, dof in enumerate(self.spring_dof):
            self.Jh[10 + k, dof] = 1.0  # rigid springs (14c): dv_spring = 0, Jdot = 0

        # Compiled-kernel inputs: the model's tree as int rows (body rows nbody long, dof rows
        # nv long, point rows: body, then eq/foot indices), and the points' local offsets.
        nb = m.nbody
        w = max(nb, nv, npt)
        topo = np.full((10, w), -1, dtype=np.int64)
        topo[0, :nb] = m.body_rootid
        topo[1, :nb] = m.body_weldid
        topo[2, :nb] = m.body_dofnum
        topo[3, :nb] = m.body_dofadr
        topo[4, :nb] = m.body_parentid
        topo[5, :nv] = m.dof_parentid
        topo[6, :nv] = m.dof_bodyid
        jt = m.jnt_type[m.dof_jntid]
        jadr = m.jnt_dofadr[m.dof_jntid]
        topo[7, :nv] = ((jt == mujoco.mjtJoint.mjJNT_BALL)
                        | ((jt == mujoco.mjtJoint.mjJNT_FREE) & (np.arange(nv) >= jadr + 3)))
        topo[8, :npt] = self._pt_body
        # row 9: [ne, pelvis, planar k (2), achilles k (2), foot axis joints (2), nbody]
        topo[9, :9] = (ne, self.pelvis_body, *self._planar_k, *self._achilles_k,
                       *self.foot_joint_axis_jnt, nb)
        self._topo = topo
        # float config: local offsets (npt x 3), then [radius, 1/mass, g, 1/subtreemass] and
        # the body masses (nbody)
        cfg = np.zeros((npt + 2 + nb, 3))
        cfg[:npt] = self._pt_local
        cfg[npt] = (FOOT_CAPSULE_RADIUS, 1.0 / self.mass, self._g)
        cfg[npt + 1, 0] = 1.0 / float(m.body_subtreemass[self.pelvis_body])
        cfg[npt + 2 :, 0] = m.body_mass
        self._ptcfg = cfg
        self._pts = np.zeros((npt, 3))
        self._Jpts = np.zeros((npt, 3, nv))
        self._acc = np.zeros((npt, 3))
        # small outputs in one buffer, the public names are views into it
        self._small = np.zeros((16 + ne, 3))
        self.R_pelvis = self._small[0:3]
        self.foot_axis = self._small[3:5]
        self.com = self._small[5]
        self.com_vel = self._small[6]
        self.com_dot_v = self._small[7]
        self.p_contact = self._small[8:12]
        self.v_contact = self._small[12:16]
        self.rod_residual = self._small[16 : 16 + ne]
        #: all of the above as one array, as the compiled task rows read it (tasks.KIN_*)
        self.kin = self._small
        # views of the point Jacobians: contact rows (14d) in world frame
        self.Jc = self._Jpts[2 * ne :].reshape(3 * self.n_contact_points, nv)
        self.Jc_dot_v = self._acc[2 * ne :].reshape(3 * self.n_contact_points)
        self.R_list = self.R_pelvis.tolist()
        # MjData arrays are views into buffers that never move: fetch the wrappers once
        self._arr = _DataViews(self.d)
        #: the state of the last ``update`` (float64, contiguous: the compiled tasks read it)
        self.q = self._arr.qpos
        self.v = self._arr.qvel
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
        a = self._arr  # the kernel's arguments: fixed objects, filled in place
        self._kargs = (self._topo, self._ptcfg, a.qvel, a.xpos, a.xmat, a.xaxis, a.xipos,
                       a.subtree_com, a.cdof, a.cdof_dot, a.cvel, a.cfrc_int, a.qfrc_bias,
                       a.qfrc_passive, self._Jpts, self._acc, self._pts, self.h, self.Jh,
                       self.Jh_dot_v, self.J_com, self._small)
        # compile the kernel (or load it from numba's on-disk cache) now, not on the first tick
        self.update(m.qpos0, np.zeros(nv))

    # ------------------------------------------------------------------ per tick
    def update(self, q: np.ndarray, v: np.ndarray) -> None:
        """Recompute every term for state (q, v): kinematics, M factor, h, Jacobians, Jdot v."""
        m, d, a = self.m, self.d, self._arr
        a.qpos[:] = q
        a.qvel[:] = v
        mujoco.mj_fwdPosition(m, d)  # kinematics, CoM, M and its factorization
        mujoco.mj_fwdVelocity(m, d)  # qfrc_bias, qfrc_passive (springs, damping), cvel, cdof_dot
        # RNE with qacc = 0: the CoM bias acceleration comes from the pelvis subtree's cfrc_int.
        a.qacc[:] = 0.0
        mujoco.mj_rnePostConstraint(m, d)
        _kinematics(*self._kargs)
        # float copies for the tasks' 3-vector arithmetic (cheaper than numpy calls)
        small = self._small.tolist()
        self.R_list = small[0:3]
        self.com_l = small[5]
        self.com_vel_l = small[6]
        self.com_dot_v_l = small[7]
        self.p_contact_l = small[8:12]
        self.v_contact_l = small[12:16]
        self.Jc_dot_v_l = self.Jc_dot_v.tolist()

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

    def foot_center_vel(self, side: int) -> np.ndarray:
        """World velocity of ``foot_center``."""
        return 0.5 * (self.v_contact[2 * side] + self.v_contact[2 * side + 1])

    def foot_center_l(self, side: int) -> list[float]:
        """``foot_center`` as a list of floats (the per-tick path)."""
        f, r = self.p_contact_l[2 * side], self.p_contact_l[2 * side + 1]
        return [0.5 * (f[0] + r[0]), 0.5 * (f[1] + r[1]), 0.5 * (f[2] + r[2])]

    def pelvis_yaw(self) -> float:
        """Yaw of the pelvis x axis in the world (rad)."""
        return math.atan2(self.R_list[1][0], self.R_list[0][0])


# ---------------------------------------------------------------------- compiled kernel
_jit = numba.njit(cache=True, nogil=True)


@_jit
def _point_jac(topo: np.ndarray, body: int, p: np.ndarray, subtree_com: np.ndarray,
               cdof: np.ndarray, cdof_dot: np.ndarray, cvel: np.ndarray, v: np.ndarray,
               J: np.ndarray, jdv: np.ndarray | None) -> None:
    """Translational Jacobian ``J`` (3, nv) of world point ``p`` fixed to ``body``, and, when
    ``jdv`` is given, ``Jdot v`` (3): MuJoCo's ``mj_jac`` and ``mj_jacDot`` (engine_core_util.c),
    a backward pass over the dof ancestor chain with ``cdof``, ``cdof_dot`` and ``cvel``."""
    for a in range(3):  # (explicit loops: slice assignments make numba compile far longer)
        for i in range(J.shape[1]):
            J[a, i] = 0.0
    root = topo[0, body]
    o0 = p[0] - subtree_com[root, 0]
    o1 = p[1] - subtree_com[root, 1]
    o2 = p[2] - subtree_com[root, 2]
    if jdv is not None:
        jdv[0] = jdv[1] = jdv[2] = 0.0
        # point velocity (mju_transformSpatial of the body's cvel to p): lin - (p - com) x ang
        cv = cvel[body]
        pv0 = cv[3] - (o1 * cv[2] - o2 * cv[1])
        pv1 = cv[4] - (o2 * cv[0] - o0 * cv[2])
        pv2 = cv[5] - (o0 * cv[1] - o1 * cv[0])
    b = topo[1, body]  # skip fixed bodies (weld id)
    if topo[2, b] == 0:
        return
    i = topo[3, b] + topo[2, b] - 1
    while i >= 0:
        c = cdof[i]
        # mj_jac: lin + ang x offset
        J[0, i] = c[3] + (c[1] * o2 - c[2] * o1)
        J[1, i] = c[4] + (c[2] * o0 - c[0] * o2)
        J[2, i] = c[5] + (c[0] * o1 - c[1] * o0)
        if jdv is not None:
            cd = cdof_dot[i]
            d0, d1, d2, d3, d4, d5 = cd[0], cd[1], cd[2], cd[3], cd[4], cd[5]
            if topo[7, i]:  # quaternion dofs: cdof_dot = cvel x cdof (motion cross product)
                w = cvel[topo[6, i]]
                d0 = -w[2] * c[1] + w[1] * c[2]
                d1 = w[2] * c[0] - w[0] * c[2]
                d2 = -w[1] * c[0] + w[0] * c[1]
                d3 = -w[2] * c[4] + w[1] * c[5]
                d4 = w[2] * c[3] - w[0] * c[5]
                d5 = -w[1] * c[3] + w[0] * c[4]
                d3 += -w[5] * c[1] + w[4] * c[2]
                d4 += w[5] * c[0] - w[3] * c[2]
                d5 += -w[4] * c[0] + w[3] * c[1]
            # mj_jacDot: cdof_dot_lin + cdof_dot_ang x offset + cdof_ang x point velocity
            vi = v[i]
            jdv[0] += (d3 + (d1 * o2 - d2 * o1) + (c[1] * pv2 - c[2] * pv1)) * vi
            jdv[1] += (d4 + (d2 * o0 - d0 * o2) + (c[2] * pv0 - c[0] * pv2)) * vi
            jdv[2] += (d5 + (d0 * o1 - d1 * o0) + (c[0] * pv1 - c[1] * pv0)) * vi
        i = topo[5, i]


@_jit
def _kinematics(topo: np.ndarray, cfg: np.ndarray, v: np.ndarray, xpos: np.ndarray,
                xmat: np.ndarray, xaxis: np.ndarray, xipos: np.ndarray,
                subtree_com: np.ndarray, cdof: np.ndarray, cdof_dot: np.ndarray,
                cvel: np.ndarray, cfrc_int: np.ndarray, qfrc_bias: np.ndarray,
                qfrc_passive: np.ndarray, Jp: np.ndarray, acc: np.ndarray, pts: np.ndarray,
                h: np.ndarray, Jh: np.ndarray, Jh_dot_v: np.ndarray, J_com: np.ndarray,
                small: np.ndarray) -> None:
    """Every per-tick term of ``CassieModel`` after MuJoCo's position and velocity passes
    (layouts in ``CassieModel.__init__``); ``small`` holds R_pelvis, foot axes, CoM (position,
    velocity, bias acceleration), contact points and velocities, rod residuals."""
    nv = v.shape[0]
    npt = pts.shape[0]
    ne = topo[9, 0]
    pelvis = topo[9, 1]
    nb = topo[9, 8]
    radius, inv_mass, g = cfg[npt, 0], cfg[npt, 1], cfg[npt, 2]
    # h = bias - passive forces, so that M dv + h = B u + Jh^T lh + Jc^T lc (13)/(14b)
    for i in range(nv):
        h[i] = qfrc_bias[i] - qfrc_passive[i]
    for a in range(9):
        small[a // 3, a % 3] = xmat[pelvis, a]
    for k in range(2):
        for a in range(3):
            small[3 + k, a] = xaxis[topo[9, 6 + k], a]
    # points: R_body local + x_body; the foot capsule's lowest point on flat ground
    for n in range(npt):
        b = topo[8, n]
        r = xmat[b]
        lo = cfg[n]
        for a in range(3):
            pts[n, a] = (r[3 * a] * lo[0] + r[3 * a + 1] * lo[1]
                         + r[3 * a + 2] * lo[2]) + xpos[b, a]
        if n >= 2 * ne:
            pts[n, 2] -= radius
        _point_jac(topo, b, pts[n], subtree_com, cdof, cdof_dot, cvel, v, Jp[n], acc[n])
    # Holonomic rows (14c): connect residual p1 - p2. Rows 0-3: the two plantar four-bars,
    # whose plane is the foot's local x-y plane (all their hinges turn about local z): the
    # in-plane rows are the foot's world x and y axes E, and d/dt(E J_r) v = E Jdot_r v
    # + Edot J_r v with Edot = -E [w]x for the foot's world angular velocity w (the second
    # term vanishes when v satisfies the closure, but keeps (14c) exact for any v).
    for j in range(2):
        k = topo[9, 2 + j]
        b2 = topo[8, ne + k]
        r = xmat[b2]
        rd0 = 0.0
        rd1 = 0.0
        rd2 = 0.0
        for i in range(nv):
            d0 = Jp[k, 0, i] - Jp[ne + k, 0, i]
            d1 = Jp[k, 1, i] - Jp[ne + k, 1, i]
            d2 = Jp[k, 2, i] - Jp[ne + k, 2, i]
            rd0 += d0 * v[i]
            rd1 += d1 * v[i]
            rd2 += d2 * v[i]
            for e in range(2):  # E row e = column e of R (the foot's world x, y axes)
                Jh[2 * j + e, i] = r[e] * d0 + r[3 + e] * d1 + r[6 + e] * d2
        w = cvel[b2]
        a0 = (acc[k, 0] - acc[ne + k, 0]) - (w[1] * rd2 - w[2] * rd1)
        a1 = (acc[k, 1] - acc[ne + k, 1]) - (w[2] * rd0 - w[0] * rd2)
        a2 = (acc[k, 2] - acc[ne + k, 2]) - (w[0] * rd1 - w[1] * rd0)
        for e in range(2):
            Jh_dot_v[2 * j + e] = r[e] * a0 + r[3 + e] * a1 + r[6 + e] * a2
    # Rows 4-9: the achilles rods (ball joints): all three rows of the connect residual.
    for j in range(2):
        k = topo[9, 4 + j]
        for a in range(3):
            for i in range(nv):
                Jh[4 + 3 * j + a, i] = Jp[k, a, i] - Jp[ne + k, a, i]
            Jh_dot_v[4 + 3 * j + a] = acc[k, a] - acc[ne + k, a]
    # rows 10..13 are the rigid springs (constant, set in __init__); their Jdot v is 0
    for k in range(ne):
        for a in range(3):
            small[16 + k, a] = pts[k, a] - pts[ne + k, a]
    # contact points (14d), world frame: positions and velocities Jc v
    for n in range(npt - 2 * ne):
        for a in range(3):
            small[8 + n, a] = pts[2 * ne + n, a]
            s = 0.0
            for i in range(nv):
                s += Jp[2 * ne + n, a, i] * v[i]
            small[12 + n, a] = s
    # Centre of mass: mj_jacSubtreeCom (mass-weighted Jacobians of the subtree's body CoMs)
    for a in range(3):
        for i in range(nv):
            J_com[a, i] = 0.0
    jb = np.empty((3, nv))
    for b in range(pelvis, nb):
        if b > pelvis and topo[4, b] < pelvis:
            break
        _point_jac(topo, b, xipos[b], subtree_com, cdof, cdof_dot, cvel, v, jb, None)
        mb = cfg[npt + 2 + b, 0]
        for a in range(3):
            for i in range(nv):
                J_com[a, i] += jb[a, i] * mb
    inv_sub = cfg[npt + 1, 0]
    for a in range(3):
        small[5, a] = subtree_com[pelvis, a]
        s = 0.0
        for i in range(nv):
            J_com[a, i] *= inv_sub
            s += J_com[a, i] * v[i]
        small[6, a] = s
        # with qacc = 0 the pelvis subtree's net force (linear part of cfrc_int) is
        # M (Jdot v)_com plus M g (MuJoCo's gravity seed): the CoM bias acceleration
        small[7, a] = cfrc_int[pelvis, 3 + a] * inv_mass
    small[7, 2] -= g


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
        self.xipos = d.xipos
        self.subtree_com = d.subtree_com
        self.cfrc_int = d.cfrc_int
        self.cvel = d.cvel
        self.cdof = d.cdof
        self.cdof_dot = d.cdof_dot


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
