"""Cassie's state estimator without transport: one robot-output packet in, one estimate out.

Per packet (2 kHz): range checks (a bad packet is rejected, never passed on), leg kinematics
with the rods solved, spring-deflection contact, the contact-aided InEKF (IMU propagation, leg
kinematics correction), the full ``q``/``v`` in MuJoCo order, and the ALIP state (CoM relative
to the stance contact, angular momentum about it) smoothed by its Kalman filter. All buffers are
preallocated; the returned ``Estimate`` is the same object every call (copy to keep it).

Two implementations of the same estimator share one state: by default each packet is one call
of the compiled step ``kernels.run`` (``step`` takes the raw datagram: validation, checks and
the whole update); ``fused=False`` composes the modular parts in Python (``LegKinematics``,
``ContactInEKF``, ``SpringContact``, ``AlipKalman`` on filterpy), as before the fused step,
and is the reference it is tested against (``tests/state_estimator``: the same estimates to
~1e-12 on recorded packets).
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field

import mujoco
import numpy as np

from runtime.cassie_packets import (
    KIND_OUTPUT,
    NUM_MOTORS,
    OUTPUT_LAYOUT,
    OUTPUT_SIZE,
    PROTOCOL_VERSION,
    OutputPacket,
    PacketError,
)

from . import kernels as K
from .alip_filter import AlipKalman
from .contact import SpringContact
from .inekf import ContactInEKF
from .kinematics import LegKinematics
from .params import EstimatorParams

log = logging.getLogger(__name__)

# estimate status bits (robot_state_t.status, low byte; see processes/state_estimator/process)
STATUS_INITIALIZING = K.STATUS_INITIALIZING  # first packets: the filter is converging
STATUS_NO_CONTACT = K.STATUS_NO_CONTACT  # neither foot in contact: position is IMU dead reckoning
STATUS_PACKET_GAP = K.STATUS_PACKET_GAP  # packets were lost just before this one
STATUS_STILL = K.STATUS_STILL  # at rest with no foot down: zero-velocity updates
#: sine of the foot pitch above which the heel or toe bears the load, and back to mid-foot
PITCH_ON, PITCH_OFF = K.PITCH_ON, K.PITCH_OFF
#: consecutive packets whose time does not advance before the target PC counts as restarted
RESTART_AFTER = 200


#: the packet's contiguous float64 fields (runtime.cassie_packets.OUTPUT_LAYOUT), in order
_FIELDS = ("imu_quat", "imu_gyro", "imu_accel", "motor_pos", "motor_vel", "motor_torque",
           "joint_pos", "joint_vel")
_F0 = OUTPUT_LAYOUT.fields["imu_quat"][1]
_NFLOAT = sum(OUTPUT_LAYOUT[f].shape[0] for f in _FIELDS)
if OUTPUT_LAYOUT.fields["joint_vel"][1] + 8 * OUTPUT_LAYOUT["joint_vel"].shape[0] != (
        _F0 + 8 * _NFLOAT):
    raise ImportError("runtime.cassie_packets layout changed: update the estimator's checks")
_FIELD_OF = [f"{f}[{i}]" for f in _FIELDS for i in range(OUTPUT_LAYOUT[f].shape[0])]


class RejectedPacket(ValueError):
    """A packet with values outside the physically plausible ranges; the message says which."""


@dataclass
class Estimate:
    """The estimator's output for one packet (preallocated, overwritten every call)."""

    nq: int
    nv: int
    utime: int = 0
    q: np.ndarray = field(init=False)  # (nq) pelvis position (world), quat (w,x,y,z), joints
    v: np.ndarray = field(init=False)  # (nv) world linear, body angular, joint rates
    in_contact: list[bool] = field(default_factory=lambda: [False, False])
    force: np.ndarray = field(default_factory=lambda: np.zeros(2))  # N, per foot
    spring_defl: np.ndarray = field(default_factory=lambda: np.zeros(2))  # shin springs, rad
    alip_stance: int = -1  # 0 left, 1 right, -1 unknown
    alip_x: np.ndarray = field(default_factory=lambda: np.zeros(4))  # filtered
    alip_raw: np.ndarray = field(default_factory=lambda: np.zeros(4))  # before the filter
    stance_pos: np.ndarray = field(default_factory=lambda: np.zeros(3))  # contact point, world
    com: np.ndarray = field(default_factory=lambda: np.zeros(3))  # world
    com_vel: np.ndarray = field(default_factory=lambda: np.zeros(3))
    status: int = 0

    def __post_init__(self) -> None:
        self.q = np.zeros(self.nq)
        self.v = np.zeros(self.nv)


class _IntSlot:
    """An integer attribute kept in the estimator's int state (``kernels`` layout ``I_*``),
    so the fused step and Python read and write the same value."""

    def __init__(self, index: int, kind: type = int) -> None:
        self.index, self.kind = index, kind

    def __get__(self, obj: CassieEstimator, owner: type | None = None) -> int | bool:
        return self.kind(obj._N[self.index])

    def __set__(self, obj: CassieEstimator, value: int | bool) -> None:
        obj._N[self.index] = int(value)


class CassieEstimator:
    """IMU + leg kinematics + contact -> floating base (InEKF), joints, contact, ALIP state.

    ``fused`` (default): each packet is one call of the compiled step (``kernels.run``);
    ``fused=False``: the modular parts composed in Python (the reference). Either way the
    parts' arrays (``filter.R``, ``kin.foot_pos``, ``est.q``...) are views of one state."""

    initialized = _IntSlot(K.I_INIT, bool)
    updates = _IntSlot(K.I_UPDATES)
    _stale = _IntSlot(K.I_STALE)
    _last_utime = _IntSlot(K.I_LAST_UTIME)
    _alip_utime = _IntSlot(K.I_ALIP_UTIME)

    def __init__(self, params: EstimatorParams | None = None,
                 model: mujoco.MjModel | None = None, fused: bool = True) -> None:
        t0 = time.perf_counter()
        self.params = p = params or EstimatorParams()
        self.fused = fused
        self.kin = LegKinematics(model)
        m = self.kin.m
        site = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, "imu")
        if site < 0 or int(m.site_bodyid[site]) != self.kin.pelvis:
            raise RuntimeError("Cassie model: expected an 'imu' site on the pelvis")
        if not np.allclose(m.site_quat[site], (1.0, 0.0, 0.0, 0.0)):
            raise RuntimeError("Cassie model: the IMU site is expected aligned with the pelvis")
        self.r_imu = m.site_pos[site].copy()  # IMU position in the pelvis frame
        self._r_imu_l = self.r_imu.tolist()
        self.filter = ContactInEKF(p.inekf, p.gravity)
        self.contact = SpringContact(p.contact)
        self.alip = AlipKalman(self.kin.mass, p.alip, p.gravity)
        self.est = Estimate(self.kin.nq, self.kin.nv)
        # joint limits for the range check (hinges only; the free joint and balls excluded)
        hinge = m.jnt_type == mujoco.mjtJoint.mjJNT_HINGE
        lo = np.full(m.nq, -np.inf)
        hi = np.full(m.nq, np.inf)
        lim = hinge & (m.jnt_limited.astype(bool))
        lo[m.jnt_qposadr[lim]] = m.jnt_range[lim, 0] - p.limits.joint_margin_rad
        hi[m.jnt_qposadr[lim]] = m.jnt_range[lim, 1] + p.limits.joint_margin_rad
        # per-double bounds, in the packet's order (_FIELDS)
        lm = p.limits
        sym = {"imu_quat": 1.0 + lm.quat_norm_tol, "imu_gyro": lm.max_gyro,
               "imu_accel": lm.max_accel, "motor_vel": lm.max_joint_vel,
               "motor_torque": lm.max_torque, "joint_vel": lm.max_joint_vel}
        los, his = [], []
        for name in _FIELDS:
            n = OUTPUT_LAYOUT[name].shape[0]
            if name == "motor_pos":
                los.append(lo[self.kin.motor_qpos])
                his.append(hi[self.kin.motor_qpos])
            elif name == "joint_pos":
                los.append(lo[self.kin.joint_qpos])
                his.append(hi[self.kin.joint_qpos])
            else:
                los.append(np.full(n, -sym[name]))
                his.append(np.full(n, sym[name]))
        self._lo = np.concatenate(los)
        self._hi = np.concatenate(his)
        self._qn_lo = (1.0 - lm.quat_norm_tol) ** 2  # bounds on the squared quaternion norm
        self._qn_hi = (1.0 + lm.quat_norm_tol) ** 2
        self._view_pkt: OutputPacket | None = None
        self._view = np.zeros(_NFLOAT)
        self.restarts = 0
        self._gyro_prev = np.zeros(3)
        self._h = np.zeros((2, 3))
        self._sole_mode = np.zeros(2, dtype=np.int64)  # per foot: 0 mid-sole, -1 / +1 the end
        self._switched = np.zeros(2, dtype=np.bool_)  # at -/+ the axis; which feet switched
        self._foot_speed = np.zeros(2)  # each foot's speed in the world, m/s
        self._quat = np.zeros(4)
        self._vb = np.zeros(3)
        self._still = False  # the reference path's last at-rest verdict (a status bit)
        self._bind()
        self.initialized = False
        self.updates = 0
        self._stale = 0
        self._last_utime = 0
        self._alip_utime = 0
        # compile (or load from the on-disk cache) the kernels now, not on the first packet
        K._in_bounds(self._lo, self._lo, self._hi, 0.0, 2.0)
        self._sole_points(np.array((0.0, 0.0, 1.0)))
        K._foot_speeds(np.eye(3), np.zeros(3), np.zeros(3), self.kin.foot_pos,
                       self.kin.foot_vel, self.r_imu, self._foot_speed)
        if fused:  # an all-zero work buffer is rejected at once (version 0): no state changes
            W, S, N, C, CI = self._args
            K.run(K.PH_CHECK, False, False, W, np.zeros(OUTPUT_SIZE, np.uint8), S, N, C, CI)
        if (setup_s := time.perf_counter() - t0) > 3.0:
            log.info("estimator set up in %.1f s: numba compiled its kernels (first start on "
                     "this machine or after a code change; cached in __pycache__ from now)",
                     setup_s)

    # -- the packed state ----------------------------------------------------------------------
    def _bind(self) -> None:
        """Move every part's state into ``kernels``' packed buffers (values kept) and make
        the parts' arrays views of them: the fused step and the Python parts share one state."""
        kin, f, c, est, a = self.kin, self.filter, self.contact, self.est, self.alip
        nq, nv = kin.nq, kin.nv
        sizes = {"KQ": nq, "KV": nv, "EQ": nq, "EV": nv, "TORQUE": NUM_MOTORS, "ACCEL": 3}
        dyn, o = {}, K.S_FIXED
        for name in K.S_DYNAMIC:
            dyn[name] = o
            o += sizes[name]
        S = self._S = np.zeros(o)
        N = self._N = np.zeros(K.I_SIZE, dtype=np.int64)

        def view(off: int, like: np.ndarray) -> np.ndarray:
            v = S[off:off + like.size].reshape(like.shape)
            v[...] = like
            return v

        f.R, f.v, f.p = view(K.S_R, f.R), view(K.S_V, f.v), view(K.S_P, f.p)
        f.d, f.P, f._scratch = view(K.S_D, f.d), view(K.S_COV, f.P), view(K.S_SCRATCH, f._scratch)
        self._gyro_prev, self._h = view(K.S_GYRO_PREV, self._gyro_prev), view(K.S_H, self._h)
        self._foot_speed = view(K.S_FOOT_SPEED, self._foot_speed)
        self._quat, self._vb = view(K.S_QUAT, self._quat), view(K.S_VB, self._vb)
        kin.foot_pos, kin.foot_axis = view(K.S_FOOT_POS, kin.foot_pos), view(K.S_FOOT_AXIS,
                                                                              kin.foot_axis)
        kin.foot_vel, kin.spring_defl = view(K.S_FOOT_VEL, kin.foot_vel), view(K.S_SPRING,
                                                                               kin.spring_defl)
        kin.com, kin.com_vel = view(K.S_COM_B, kin.com), view(K.S_COMVEL_B, kin.com_vel)
        kin.angmom_com = view(K.S_ANGMOM_B, kin.angmom_com)
        kin.q, kin.v = view(dyn["KQ"], kin.q), view(dyn["KV"], kin.v)
        c.force = view(K.S_FORCE, c.force)
        est.force, est.spring_defl = view(K.S_EST_FORCE, est.force), view(K.S_EST_SPRING,
                                                                          est.spring_defl)
        est.alip_x, est.alip_raw = view(K.S_ALIP_X, est.alip_x), view(K.S_ALIP_RAW,
                                                                      est.alip_raw)
        est.stance_pos = view(K.S_STANCE_POS, est.stance_pos)
        est.com, est.com_vel = view(K.S_EST_COM, est.com), view(K.S_EST_COMVEL, est.com_vel)
        est.q, est.v = view(dyn["EQ"], est.q), view(dyn["EV"], est.v)
        S[K.S_KF_R:K.S_KF_R + 16] = a.kf.R.ravel()  # the ALIP filter of the fused step
        S[K.S_KF_DT] = -1.0
        self._sole_mode = N[K.I_MODE:K.I_MODE + 2]
        N[K.I_EST_STANCE] = N[K.I_ALIP_STANCE] = -1
        if self.fused:  # the flags the compiled step keeps; the reference keeps Python lists
            f.contact = N[K.I_FC:K.I_FC + 2]
            c.in_contact = N[K.I_CC:K.I_CC + 2]
        #: what the process publishes: the int block (utime, status, ALIP stance, the two
        #: contact flags, whether the ALIP fields changed, the target PC's status bits) and
        #: the float block q (nq), v (nv), motor torques (10), IMU specific force (3)
        self.out_ints = N[:K.I_OUT]
        self.out_floats = S[dyn["EQ"]:dyn["ACCEL"] + 3]
        self._torque_out = S[dyn["TORQUE"]:dyn["TORQUE"] + NUM_MOTORS]
        self._accel_out = S[dyn["ACCEL"]:dyn["ACCEL"] + 3]
        # constants
        p = self.params
        C = np.zeros(K.C_SIZE)
        C[K.C_PROTO], C[K.C_PROTO + 1] = PROTOCOL_VERSION, KIND_OUTPUT
        C[K.C_LO:K.C_LO + K.W_NCHECK] = self._lo
        C[K.C_HI:K.C_HI + K.W_NCHECK] = self._hi
        C[K.C_QN_LO], C[K.C_QN_HI] = self._qn_lo, self._qn_hi
        C[K.C_R_IMU:K.C_R_IMU + 3] = self.r_imu
        C[K.C_G:K.C_G + 3] = f.g
        C[K.C_VAR_G], C[K.C_VAR_A], C[K.C_VAR_C] = f._var_g, f._var_a, f._var_c
        C[K.C_VAR_S], C[K.C_KIN_VAR] = f._var_s, f._kin_var
        C[K.C_STILL_GYRO], C[K.C_STILL_ACCEL] = p.still.gyro_rad_s, p.still.accel_m_s2
        C[K.C_STILL_AFTER_US] = p.still.after_s * 1e6
        C[K.C_STILL_VAR] = p.still.velocity_std_m_s ** 2
        N[K.I_STILL_SINCE] = -1
        C[K.C_GAIN:K.C_GAIN + 2] = c._gain
        C[K.C_ON_N], C[K.C_OFF_N] = p.contact.on_n, p.contact.off_n
        C[K.C_TD_SPEED] = p.contact.touchdown_speed_mps
        C[K.C_FOOT_RADIUS], C[K.C_FOOT_HALF] = kin.foot_radius, kin.foot_half_length
        C[K.C_MASS] = kin.mass
        for off, arr in ((K.C_TGT_OFF, kin._tgt_off), (K.C_ACH_DIR, kin._ach_dir),
                         (K.C_PLA_AXIS, kin._pla_axis), (K.C_PLA_TIP_PROJ, kin._pla_tip_proj),
                         (K.C_ROD_TIP, kin._rod_tip), (K.C_FOOT_LOCAL, kin._foot_local),
                         (K.C_SPRING_REF, kin.spring_ref)):
            C[off:off + arr.size] = arr.ravel()
        CI = np.zeros(K.CI_SIZE, dtype=np.int64)
        for off, arr in ((K.CI_MOTOR_QPOS, kin.motor_qpos), (K.CI_MOTOR_DOF, kin.motor_dof),
                         (K.CI_JOINT_QPOS, kin.joint_qpos), (K.CI_JOINT_DOF, kin.joint_dof),
                         (K.CI_ACH_QPOS, kin._ach_qpos), (K.CI_PLA_QPOS, kin._pla_qpos),
                         (K.CI_ACH_DOF, kin._ach_dof), (K.CI_PLA_DOF, kin._pla_dof),
                         (K.CI_ROD_BODY, kin._rod_body), (K.CI_TGT_BODY, kin._tgt_body),
                         (K.CI_FOOT_BODY, kin.foot_body), (K.CI_SPRING_QPOS, kin.spring_qpos)):
            CI[off:off + arr.size] = np.asarray(arr).ravel()
        m, d = kin.m, kin.d
        CI[K.CI_PELVIS], CI[K.CI_NQ], CI[K.CI_NV], CI[K.CI_NBODY] = kin.pelvis, nq, nv, m.nbody
        for name in K.S_DYNAMIC:
            CI[K.CI_OFF[name]] = dyn[name]
        CI[K.CI_FN:K.CI_FN + len(K.MJ_FUNCTIONS)] = K.mujoco_functions()
        CI[K.CI_MODEL], CI[K.CI_DATA] = m._address, d._address
        # MjData's arrays live as long as d (kin.d) and never move
        for off, arr in ((K.CI_QPOS, kin._qpos), (K.CI_QVEL, kin._qvel), (K.CI_XPOS, kin._xpos),
                         (K.CI_XMAT, kin._xmat), (K.CI_CVEL, kin._cvel),
                         (K.CI_SUBTREE_COM, kin._subtree_com),
                         (K.CI_SUBTREE_LINVEL, d.subtree_linvel),
                         (K.CI_SUBTREE_ANGMOM, d.subtree_angmom)):
            if not arr.flags.c_contiguous or arr.dtype != np.float64:
                raise RuntimeError("MjData arrays are expected C-contiguous float64")
            CI[off] = arr.ctypes.data
        self._W = np.zeros(K.W_SIZE, dtype=np.uint8)
        self._wmv = memoryview(self._W)[4:]  # the datagram's bytes go here
        self._args = (self._W, S, N, C, CI)
        self._pb_pkt: OutputPacket | None = None
        self._pb = np.zeros(OUTPUT_SIZE, dtype=np.uint8)

    def _buffer_of(self, pkt: OutputPacket) -> np.ndarray:
        """A uint8 view of ``pkt``'s buffer (cached), which the fused step copies into."""
        if self._pb_pkt is not pkt:
            self._pb_pkt = pkt
            self._pb = np.frombuffer(pkt.buffer, dtype=np.uint8)
        return self._pb

    # -- validation --------------------------------------------------------------------------
    def check(self, pkt: OutputPacket) -> None:
        """Raise ``RejectedPacket`` when a decoded packet holds implausible values.

        One vectorised comparison of all 56 doubles against per-field bounds; the reason is
        worked out only when a packet fails."""
        x = self._floats_of(pkt)
        if not K._in_bounds(x, self._lo, self._hi, self._qn_lo, self._qn_hi):
            raise RejectedPacket(self._reason(pkt, x, float(x[0:4] @ x[0:4])))
        if self.initialized and pkt.utime <= self._last_utime:
            self._stale += 1
            if self._stale >= RESTART_AFTER:
                # time keeps running from an earlier point: the target PC was restarted
                log.warning("robot-output time went back to %.4f s for %d packets: target PC "
                            "restarted, re-initialising the estimator", pkt.utime * 1e-6,
                            self._stale)
                self.restarts += 1
                self.initialized = False
                self._stale = 0
                return
            raise RejectedPacket(f"utime {pkt.utime} does not advance (last {self._last_utime})")
        self._stale = 0

    def _floats_of(self, pkt: OutputPacket) -> np.ndarray:
        """A float64 view of the packet's 56 doubles from imu_quat to joint_vel (cached)."""
        if self._view_pkt is not pkt:
            self._view_pkt = pkt
            self._view = np.frombuffer(pkt.buffer, dtype="<f8", count=_NFLOAT, offset=_F0)
        return self._view

    def _reason(self, pkt: OutputPacket, x: np.ndarray, n: float) -> str:
        bad = np.flatnonzero(~((x >= self._lo) & (x <= self._hi)))
        if bad.size:
            i = int(bad[0])
            return (f"{_FIELD_OF[i]} = {x[i]:.4g} is outside [{self._lo[i]:.4g}, "
                    f"{self._hi[i]:.4g}]")
        return f"IMU quaternion norm {np.sqrt(n):.3f} is not 1"

    # -- one datagram ------------------------------------------------------------------------
    def step(self, data: bytes, pkt: OutputPacket, alip: bool = True) -> int:
        """Validate, check and estimate from one raw datagram, decoding it into ``pkt``.

        Raises ``PacketError`` (not a valid packet: ``OutputPacket.decode``'s message) or
        ``RejectedPacket`` (``check``) as decode + check + update did; returns ``kernels.OK``,
        or ``kernels.E_NONFINITE`` when the estimate is not finite (the caller drops it and
        sets ``initialized = False``). The results are in ``out_ints``, ``out_floats``,
        ``est.alip_x``, ``est.stance_pos``, ``est.spring_defl`` and ``est.force``; the
        ``STATUS_PACKET_GAP`` bit is the caller's to add (it counts the link). ``alip``: as
        for ``update``."""
        if not self.fused:
            pkt.decode(data)
            self.check(pkt)
            e = self._update_reference(pkt, False, alip)
            n = self._N
            n[K.I_UTIME], n[K.I_STATUS], n[K.I_EST_STANCE] = e.utime, e.status, e.alip_stance
            n[K.I_FC], n[K.I_FC + 1] = e.in_contact
            n[K.I_DIRTY], n[K.I_TARGET_STATUS] = 1, pkt.status
            self._torque_out[:] = pkt.motor_torque
            self._accel_out[:] = pkt.imu_accel
            ok = (np.isfinite(e.q).all() and np.isfinite(e.v).all()
                  and np.isfinite(e.alip_x).all())
            return K.OK if ok else K.E_NONFINITE
        if len(data) != OUTPUT_SIZE:
            pkt.decode(data)  # raises PacketError, saying why
        self._wmv[:] = data
        code = self._run(K.PH_CHECK, alip, False, pkt)
        if code == K.E_DECODE:
            pkt.decode(data)  # raises PacketError, saying why
            raise PacketError("robot output packet rejected by the estimator's decoder")
        if code in (K.E_RANGE, K.E_STALE):
            self.check(pkt)  # raises RejectedPacket, or re-initialises (a restarted target PC)
            if code == K.E_RANGE:
                raise RejectedPacket("packet rejected by the estimator's range check")
            code = self._run(K.PH_KIN, alip, False, pkt)
        return code

    def _run(self, phase: int, alip: bool, gap: bool, pkt: OutputPacket) -> int:
        """``kernels.run`` from ``phase``, serving the rare steps it leaves to Python."""
        W, S, N, C, CI = self._args
        pb = self._buffer_of(pkt)
        code = K.run(phase, alip, gap, W, pb, S, N, C, CI)
        while code > 0:
            if code == K.NEED_INIT:
                self._initialize(pkt)
                phase = K.PH_ESTIMATE
            elif code == K.NEED_SVD:  # keep R on SO(3) against round-off
                u, _, vt = np.linalg.svd(self.filter.R)
                self.filter.R[:] = u @ vt
                phase = K.PH_ESTIMATE
            else:  # NEED_ALIP_F: discretise the ALIP model for this step (AlipKalman._set_dt)
                dt = float(S[K.S_ALIP_DT])
                F, Q = self.alip.discretise(dt)
                S[K.S_KF_F:K.S_KF_F + 16] = F.ravel()
                S[K.S_KF_Q:K.S_KF_Q + 16] = Q.ravel()
                S[K.S_KF_DT] = dt
                phase = K.PH_ALIP
            code = K.run(phase, alip, gap, W, pb, S, N, C, CI)
        return code

    # -- the update --------------------------------------------------------------------------
    def update(self, pkt: OutputPacket, gap: bool = False, alip: bool = True) -> Estimate:
        """Estimate from one decoded packet (``check`` it first); ``gap``: packets were lost.

        ``alip``: also update the CoM, the angular momentum and the ALIP Kalman filter (the
        MPFC's input); the process asks for it on the packets it sends to the laptop (200 Hz),
        the rest of the estimate is updated on every packet."""
        if not self.fused:
            return self._update_reference(pkt, gap, alip)
        self._wmv[:] = pkt.buffer
        self._run(K.PH_KIN, alip, gap, pkt)
        n, e = self._N, self.est
        e.utime, e.status = int(n[K.I_UTIME]), int(n[K.I_STATUS])
        e.alip_stance = int(n[K.I_EST_STANCE])
        e.in_contact[0], e.in_contact[1] = bool(n[K.I_FC]), bool(n[K.I_FC + 1])
        return e

    def _update_reference(self, pkt: OutputPacket, gap: bool, alip: bool) -> Estimate:
        """``update`` by the modular parts in Python (the reference of the fused step)."""
        kin, f = self.kin, self.filter
        kin.update(pkt.motor_pos, pkt.motor_vel, pkt.joint_pos, pkt.joint_vel)
        utime = pkt.utime
        if not self.initialized:
            self._initialize(pkt)
        else:
            dt = (utime - self._last_utime) * 1e-6
            # gyro of the previous sample (zero-order hold over the interval), accel of this
            # one (MuJoCo's accelerometer is computed during the step that led here)
            f.propagate(self._gyro_prev, pkt.imu_accel, dt)
        self._last_utime = utime
        self._gyro_prev[:] = pkt.imu_gyro
        switched = self._sole_points(f.R[2])
        # contact from the springs (a contact starts only on a slow foot), then the
        # contact-aided correction (Hartley Sec. 6)
        K._foot_speeds(f.R, f.v, pkt.imu_gyro, kin.foot_pos, kin.foot_vel, self.r_imu,
                       self._foot_speed)
        self.contact.update(kin.spring_defl, self._foot_speed)
        flags = self.contact.in_contact
        h = self._h
        for k in (0, 1):
            if flags[k] and (not f.contact[k] or switched[k]):
                f.touchdown(k, h[k])  # a new contact point: (re)seed its slot
            elif not flags[k] and f.contact[k]:
                f.liftoff(k)
        f.correct(h)
        # at rest with no foot down (the holder): a zero-velocity update (kernels._still)
        C = self._args[3]
        self._still = K._still(self._N, C, utime, bool(f.contact[0] or f.contact[1]),
                               pkt.imu_gyro, pkt.imu_accel)
        if self._still:
            f.correct_still(C[K.C_STILL_VAR])
        self._fill(pkt, gap, alip)
        self.updates += 1
        return self.est

    def _sole_points(self, up: np.ndarray) -> np.ndarray:
        """The point of each line foot that bears on the ground, from the IMU (IMU frame).

        Flat, the sole under the capsule centre; pitched more than ``PITCH_ON``, the sole under
        the lower end (heel or toe), back to the centre below ``PITCH_OFF``. Each choice is a
        point that stays put while the foot rolls about it; a switch starts a new contact.
        ``up`` is the world z axis in the pelvis frame. Returns which feet switched.
        """
        kin = self.kin
        K._sole_points(kin.foot_pos, kin.foot_axis, up, self.r_imu, kin.foot_radius,
                       kin.foot_half_length, self._sole_mode, self._h, self._switched)
        return self._switched

    def _initialize(self, pkt: OutputPacket) -> None:
        """First packet: orientation from the IMU, at rest, the lower sole on ``ground_z``."""
        p = self.params
        R = np.zeros(9)
        mujoco.mju_quat2Mat(R, pkt.imu_quat / np.linalg.norm(pkt.imu_quat))
        R = R.reshape(3, 3)
        self._sole_mode[:] = 0
        self._sole_points(R[2])
        feet_w = (self._h + self.r_imu) @ R.T  # sole points relative to the pelvis, world axes
        z = p.init.ground_z_m - feet_w[:, 2].min()
        pelvis = np.array((p.init.xy_m[0], p.init.xy_m[1], z))
        self.filter.reset(R, np.zeros(3), pelvis + R @ self.r_imu)
        self.contact.in_contact[:] = [False, False]
        self.alip.stance = -1
        self.est.alip_stance = -1
        n = self._N  # the same for the fused step's copies of the last two
        n[K.I_ALIP_STANCE] = n[K.I_EST_STANCE] = n[K.I_STILL_SINCE] = -1
        n[K.I_DIRTY] = 1
        self.updates = 0
        self.initialized = True

    def _fill(self, pkt: OutputPacket, gap: bool, alip: bool = True) -> None:
        """Write ``q``, ``v``, contact and the ALIP state into the preallocated estimate.

        3-vector arithmetic is scalar Python on purpose: cheaper than numpy's per-call cost.
        """
        kin, f, est = self.kin, self.filter, self.est
        R = f.R
        rl = R.tolist()
        (r00, r01, r02), (r10, r11, r12), (r20, r21, r22) = rl
        w = pkt.imu_gyro  # pelvis angular velocity, body frame (IMU aligned with the pelvis)
        w0, w1, w2 = w.tolist()
        q, v = est.q, est.v
        q[7:] = kin.q[7:]
        v[6:] = kin.v[6:]
        # pelvis origin from the IMU point: p - R r, v - R (w x r)
        x, y, z = self._r_imu_l
        px, py, pz = f.p.tolist()
        q[0] = px - (r00 * x + r01 * y + r02 * z)
        q[1] = py - (r10 * x + r11 * y + r12 * z)
        q[2] = pz - (r20 * x + r21 * y + r22 * z)
        c0, c1, c2 = w1 * z - w2 * y, w2 * x - w0 * z, w0 * y - w1 * x
        vx, vy, vz = f.v.tolist()
        vx -= r00 * c0 + r01 * c1 + r02 * c2
        vy -= r10 * c0 + r11 * c1 + r12 * c2
        vz -= r20 * c0 + r21 * c1 + r22 * c2
        v[0], v[1], v[2] = vx, vy, vz
        mujoco.mju_mat2Quat(self._quat, R.reshape(9))
        q[3:7] = self._quat
        v[3:6] = w
        est.utime = pkt.utime
        est.in_contact[0], est.in_contact[1] = f.contact[0], f.contact[1]
        est.force[:] = self.contact.force
        est.spring_defl[:] = kin.spring_defl[:, 0]
        k0, k1 = f.contact
        status = 0
        if self.updates < 200:
            status |= STATUS_INITIALIZING
        if not (k0 or k1):
            status |= STATUS_NO_CONTACT
        if gap:
            status |= STATUS_PACKET_GAP
        if self._still:
            status |= STATUS_STILL
        est.status = status
        if not alip:
            return  # CoM, momentum and the ALIP filter run at the laptop's rate
        # ALIP state (Section III-A): CoM relative to the stance contact point, momentum about it
        vb = self._vb  # pelvis velocity in the pelvis frame, R^T v
        vb[0] = r00 * vx + r10 * vy + r20 * vz
        vb[1] = r01 * vx + r11 * vy + r21 * vz
        vb[2] = r02 * vx + r12 * vy + r22 * vz
        kin.update_momentum(vb, w)
        # the CoM, its velocity and the momentum about it, from the pelvis frame to the world
        # (the reference path: numpy products, where the fused step writes out the sums)
        cx, cy, cz = (q[0:3] + R @ kin.com).tolist()
        gx, gy, gz = (R @ kin.com_vel).tolist()
        lwx, lwy, _ = (R @ kin.angmom_com).tolist()
        com, cv = est.com, est.com_vel
        com[0], com[1], com[2] = cx, cy, cz
        cv[0], cv[1], cv[2] = gx, gy, gz
        stance = est.alip_stance
        if k0 != k1:
            stance = 0 if k0 else 1
        elif k0 and stance < 0:
            stance = 0  # double stance from the start: the left foot, by convention
        if stance < 0:
            est.alip_stance = -1
            return
        sx, sy, sz = f.d[stance].tolist()  # the stance foot's sole contact point
        sp = est.stance_pos
        sp[0], sp[1], sp[2] = sx, sy, sz
        ex, ey, ez = cx - sx, cy - sy, cz - sz
        m = kin.mass
        # L_p = L_com + m (c - p) x v_com (angular momentum transfer), world axes
        raw = est.alip_raw
        raw[0], raw[1] = ex, ey
        raw[2] = lwx + m * (ey * gz - ez * gy)
        raw[3] = lwy + m * (ez * gx - ex * gz)
        dt = (pkt.utime - self._alip_utime) * 1e-6 if est.alip_stance == stance else 0.0
        self._alip_utime = pkt.utime
        est.alip_x[:] = self.alip.step(raw, stance, dt)
        est.alip_stance = stance
