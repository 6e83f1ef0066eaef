"""The binary UDP protocol between Cassie's target PC (here: the MuJoCo sim) and the NUC.

Modelled on the robot's link: fixed-size little-endian datagrams that both start with a 2-byte
header (own sequence number, last sequence number received from the peer), so each end counts
the peer's lost packets and the round-trip delay in cycles. The NUC's state estimator and
torque bridge import this module, the sim produces the other side.

Protocol version 2 (version 1 had no pairing token). Every packet::

    offset size type     field
    0      1    uint8    seq        sender's own sequence number, +1 per packet, wraps 255 -> 0
    1      1    uint8    ack        last ``seq`` the sender received from its peer (0 before any)
    2      1    uint8    version    PROTOCOL_VERSION (2)
    3      1    uint8    kind       ord('S') robot output, ord('T') torque input

Robot output, target PC -> NUC (``kind = 'S'``), 476 bytes::

    4      8    int64     utime         sim time of this state, microseconds
    12     32   4 x f64   imu_quat      pelvis IMU orientation (w, x, y, z), world <- IMU
    44     24   3 x f64   imu_gyro      angular velocity, IMU frame, rad/s
    68     24   3 x f64   imu_accel     specific force (accelerometer), IMU frame, m/s^2
    92     80   10 x f64  motor_pos     joint-side motor positions, rad (MOTOR_NAMES order)
    172    80   10 x f64  motor_vel     joint-side motor velocities, rad/s
    252    80   10 x f64  motor_torque  torque actually applied at the joint, N m
    332    64   8 x f64   joint_pos     passive joints (JOINT_NAMES order: shin, tarsus,
                                        heel spring, foot crank; left then right), rad
    396    64   8 x f64   joint_vel     the same, rad/s
    460    8    f64       task_time_s   target PC task execution time of the previous cycle, s
    468    4    uint32    overruns      target PC cycles that missed their 0.5 ms slot
    472    4    uint32    status        STATUS_* bit flags

Torque input, NUC -> target PC (``kind = 'T'``), 92 bytes::

    4      4    uint32   token            the launch's pairing token (``link_token``)
    8      80   10 x f64 torque           joint-side motor torque commands, N m (MOTOR_NAMES)
    88     4    uint32   flags            FLAG_* bits (FLAG_RELEASE_HOLDER)

A packet is rejected with ``PacketError`` (and the receiver counts it) when its length is not
exactly the layout's size, the version or kind byte is wrong, or any float is NaN or inf. The
target PC applies torques only from the bridge it is paired with: a torque packet whose token
is not the launch's is counted as foreign and dropped (``LinkCounter.foreign``). The token is
pairing, not security: it keeps a bridge left over from another run, a second stack or a test
tool from commanding the robot.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

import numba
import numpy as np

from runtime.pairing import DEFAULT_TOKEN

PROTOCOL_VERSION = 2
KIND_OUTPUT = ord("S")
KIND_INPUT = ord("T")

#: The 10 motors, in packet order (the MuJoCo model's actuator order).
MOTOR_NAMES: tuple[str, ...] = (
    "left-hip-roll", "left-hip-yaw", "left-hip-pitch", "left-knee", "left-foot",
    "right-hip-roll", "right-hip-yaw", "right-hip-pitch", "right-knee", "right-foot",
)
#: The passive (unactuated) measured joints, in packet order.
JOINT_NAMES: tuple[str, ...] = (
    "left-shin", "left-tarsus", "left-heel-spring", "left-foot-crank",
    "right-shin", "right-tarsus", "right-heel-spring", "right-foot-crank",
)
NUM_MOTORS = len(MOTOR_NAMES)
NUM_JOINTS = len(JOINT_NAMES)

# status bits of the output packet
STATUS_HOLDER_ENGAGED = 1 << 0  # the start-up pelvis holder is still holding the robot
STATUS_WATCHDOG_TRIPPED = 1 << 1  # no command for the watchdog period: torques are zero
STATUS_SLOWER_THAN_REALTIME = 1 << 2  # the last second of sim ran slower than the wall clock
STATUS_LOCKSTEP = 1 << 3  # the target PC steps only when a command answers its state

# flag bits of the input packet
FLAG_RELEASE_HOLDER = 1 << 0  # ask the target PC to release the start-up pelvis holder

_HEADER_FIELDS = [("seq", "u1"), ("ack", "u1"), ("version", "u1"), ("kind", "u1")]

OUTPUT_LAYOUT = np.dtype(
    [
        *_HEADER_FIELDS,
        ("utime", "<i8"),
        ("imu_quat", "<f8", (4,)),
        ("imu_gyro", "<f8", (3,)),
        ("imu_accel", "<f8", (3,)),
        ("motor_pos", "<f8", (NUM_MOTORS,)),
        ("motor_vel", "<f8", (NUM_MOTORS,)),
        ("motor_torque", "<f8", (NUM_MOTORS,)),
        ("joint_pos", "<f8", (NUM_JOINTS,)),
        ("joint_vel", "<f8", (NUM_JOINTS,)),
        ("task_time_s", "<f8"),
        ("overruns", "<u4"),
        ("status", "<u4"),
    ]
)
INPUT_LAYOUT = np.dtype([*_HEADER_FIELDS, ("token", "<u4"), ("torque", "<f8", (NUM_MOTORS,)),
                         ("flags", "<u4")])

OUTPUT_SIZE = OUTPUT_LAYOUT.itemsize  # 476
INPUT_SIZE = INPUT_LAYOUT.itemsize  # 92
_FLAGS_AT = INPUT_LAYOUT.fields["flags"][1]  # byte offset of InputPacket.flags
#: byte offset of the torque packet's pairing token
TOKEN_AT = INPUT_LAYOUT.fields["token"][1]
#: ... and of the robot output's utime (int64)
UTIME_AT = OUTPUT_LAYOUT.fields["utime"][1]


class PacketError(ValueError):
    """A datagram that is not a valid packet of the expected kind; the message says why."""


class Packet:
    """One preallocated packet: a byte buffer plus named numpy views onto its fields.

    Writing a field view (``pkt.motor_pos[:] = q``) writes the bytes in place, so encoding at
    2 kHz allocates nothing; ``decode`` validates a datagram and copies it into the buffer in
    one compiled call.
    """

    LAYOUT: ClassVar[np.dtype] = OUTPUT_LAYOUT
    KIND: ClassVar[int] = KIND_OUTPUT
    NAME: ClassVar[str] = "packet"

    def __init__(self) -> None:
        self.buffer = bytearray(self.LAYOUT.itemsize)
        self.view = memoryview(self.buffer)
        #: the packet's bytes as a numpy array (for compiled code filling the packet)
        self.bytes_array = np.frombuffer(self.buffer, dtype=np.uint8)
        self._record = np.frombuffer(self.buffer, dtype=self.LAYOUT)  # shape (1,), writable
        # what decode checks, for the compiled check: version, kind, then the byte offset
        # of every float64 of the layout (each must be finite)
        self._check_spec = np.array(
            [PROTOCOL_VERSION, self.KIND, *(o + 8 * k for o, c, _ in _float_spans(self.LAYOUT)
                                            for k in range(c))], dtype=np.int64)
        #: the layout's float64 fields as one array (they are adjacent: ``float_block``)
        offset, count = float_block(self.LAYOUT)
        self.floats = np.frombuffer(self.buffer, dtype="<f8", count=count, offset=offset)
        self._record["version"] = PROTOCOL_VERSION
        self._record["kind"] = self.KIND
        _check_and_copy(b"", self.bytes_array, self._check_spec)  # compiled (or cached) now

    def field(self, name: str) -> np.ndarray:
        """A writable view of one field (shape () for scalars, (n,) for arrays)."""
        return self._record[name][0] if self.LAYOUT[name].shape else self._record[name]

    @property
    def seq(self) -> int:
        return self.buffer[0]

    @property
    def ack(self) -> int:
        return self.buffer[1]

    def encode(self, seq: int, ack: int) -> memoryview:
        """Stamp the header and return the packet's bytes (a view: copy before reuse)."""
        buf = self.buffer
        buf[0] = seq & 0xFF
        buf[1] = ack & 0xFF
        return self.view

    def to_bytes(self, seq: int, ack: int) -> bytes:
        """Stamp the header and return an immutable copy of the packet (for ``ctx.publish``)."""
        return bytes(self.encode(seq, ack))

    def decode(self, data: bytes | bytearray | memoryview) -> Packet:
        """Validate ``data`` and copy it into this packet; raises ``PacketError`` if invalid.

        The packet is left unchanged when ``data`` is rejected, so the last good one survives.
        """
        err = _check_and_copy(data, self.bytes_array, self._check_spec)
        if err:
            self._reject(err, data)
        return self

    def _reject(self, err: int, data: bytes | bytearray | memoryview) -> None:
        """Raise the ``PacketError`` saying why ``_check_and_copy`` returned ``err``."""
        if err == _BAD_SIZE:
            raise PacketError(
                f"{self.NAME} packet has {len(data)} bytes, expected exactly "
                f"{self.LAYOUT.itemsize} (protocol version {PROTOCOL_VERSION})"
            )
        if err == _BAD_VERSION:
            raise PacketError(
                f"{self.NAME} packet has protocol version {data[2]}, this end speaks "
                f"{PROTOCOL_VERSION}: rebuild both ends from the same runtime.cassie_packets"
            )
        if err == _BAD_KIND:
            raise PacketError(
                f"{self.NAME} packet has kind byte {data[3]:#04x}, expected {self.KIND:#04x} "
                f"({chr(self.KIND)!r}): is the peer sending to the wrong port?"
            )
        raise PacketError(f"{self.NAME} packet field {self._non_finite(data)!r} "
                          "holds NaN or inf")

    def _non_finite(self, data: bytes | bytearray | memoryview) -> str:
        """Name of the first float field of ``data`` holding NaN or inf (error path only)."""
        rec = np.frombuffer(data, dtype=self.LAYOUT)
        for name in self.LAYOUT.names:
            if self.LAYOUT[name].base.kind == "f" and not np.isfinite(rec[name]).all():
                return name
        return "?"


_BAD_SIZE, _BAD_VERSION, _BAD_KIND, _NON_FINITE = 1, 2, 3, 4


@numba.njit(cache=True, nogil=True)
def _check_and_copy(data: Any, out: np.ndarray, spec: np.ndarray) -> int:  # pragma: no cover
    """Validate datagram ``data`` as the packet ``spec`` describes and copy it into ``out``.

    Returns 0 (copied), or why it was rejected (``out`` untouched): ``_BAD_SIZE`` (not exactly
    ``out``'s size), ``_BAD_VERSION``, ``_BAD_KIND``, or ``_NON_FINITE`` (a NaN or inf in the
    float64 at one of the byte offsets ``spec[2:]``: all 11 exponent bits set, read from the
    little-endian bytes, which is what ``np.isfinite`` tests).
    """
    n = out.shape[0]
    if len(data) != n:
        return _BAD_SIZE
    if data[2] != spec[0]:
        return _BAD_VERSION
    if data[3] != spec[1]:
        return _BAD_KIND
    for j in range(2, spec.shape[0]):
        o = spec[j]
        if (data[o + 7] & 0x7F) == 0x7F and (data[o + 6] & 0xF0) == 0xF0:
            return _NON_FINITE
    for i in range(n):
        out[i] = data[i]
    return 0


def _float_spans(layout: np.dtype) -> list[tuple[int, int, str]]:
    """Runs of adjacent float64 fields as (offset, count, field names): one check per run."""
    spans: list[tuple[int, int, str]] = []
    for name in layout.names:
        sub, offset = layout.fields[name][:2]
        if sub.base.kind != "f":
            continue
        count = sub.itemsize // 8
        if spans and spans[-1][0] + 8 * spans[-1][1] == offset:
            o, c, n = spans[-1]
            spans[-1] = (o, c + count, f"{n}, {name}")
        else:
            spans.append((offset, count, name))
    return spans


def float_block(layout: np.dtype) -> tuple[int, int]:
    """(byte offset, count) of the one run of adjacent float64 fields of ``layout``."""
    spans = _float_spans(layout)
    if len(spans) != 1:
        raise ValueError(f"the layout has {len(spans)} runs of float fields, expected one")
    return spans[0][0], spans[0][1]


class OutputPacket(Packet):
    """Robot output, target PC -> NUC: IMU, motors, passive joints, target-PC status."""

    LAYOUT = OUTPUT_LAYOUT
    KIND = KIND_OUTPUT
    NAME = "robot output"

    def __init__(self) -> None:
        super().__init__()
        self.imu_quat = self.field("imu_quat")
        self.imu_gyro = self.field("imu_gyro")
        self.imu_accel = self.field("imu_accel")
        self.motor_pos = self.field("motor_pos")
        self.motor_vel = self.field("motor_vel")
        self.motor_torque = self.field("motor_torque")
        self.joint_pos = self.field("joint_pos")
        self.joint_vel = self.field("joint_vel")
        self._utime = self.field("utime")
        self._task = self.field("task_time_s")
        self._overruns = self.field("overruns")
        self._status = self.field("status")

    @property
    def utime(self) -> int:
        return int(self._utime[0])

    @utime.setter
    def utime(self, value: int) -> None:
        self._utime[0] = value

    @property
    def task_time_s(self) -> float:
        return float(self._task[0])

    @task_time_s.setter
    def task_time_s(self, value: float) -> None:
        self._task[0] = value

    @property
    def overruns(self) -> int:
        return int(self._overruns[0])

    @overruns.setter
    def overruns(self, value: int) -> None:
        self._overruns[0] = value & 0xFFFFFFFF

    @property
    def status(self) -> int:
        return int(self._status[0])

    @status.setter
    def status(self, value: int) -> None:
        self._status[0] = value


class InputPacket(Packet):
    """Torque input, NUC -> target PC: the 10 joint-side motor torques and flag bits."""

    LAYOUT = INPUT_LAYOUT
    KIND = KIND_INPUT
    NAME = "torque input"

    def __init__(self, token: int = DEFAULT_TOKEN) -> None:
        super().__init__()
        self.torque = self.field("torque")
        self._flags = self.field("flags")
        self.field("token")[0] = token  # set once: every packet this bridge sends carries it

    @property
    def flags(self) -> int:
        b, o = self.buffer, _FLAGS_AT  # uint32, little-endian (bytearray reads: no numpy)
        return b[o] | b[o + 1] << 8 | b[o + 2] << 16 | b[o + 3] << 24

    @flags.setter
    def flags(self, value: int) -> None:
        self._flags[0] = value


@dataclass
class LinkCounter:
    """Sequence bookkeeping for one end of the link: own seq, lost packets, round trip.

    Call ``next_seq()`` for each packet sent (stamp it with ``ack=last_peer_seq``) and
    ``on_receive(seq, ack)`` for each valid packet received. With 8-bit sequence numbers a
    jump of more than 127 is ambiguous (an outage of over 127 packets, a restarted peer, or an
    old packet arriving late): it is counted as a resync, the count of lost packets is not
    changed, and counting restarts from the new number.
    """

    sent: int = 0
    received: int = 0
    lost: int = 0  # peer packets that never arrived (gaps in the peer's seq)
    duplicates: int = 0  # same seq again (retransmits)
    resyncs: int = 0  # ambiguous jumps of more than 127 (outage, restart, late packet)
    malformed: int = 0  # datagrams rejected by decode (counted by the caller via ``on_error``)
    foreign: int = 0  # well-formed packets with another launch's pairing token (dropped)
    own_seq: int = -1  # seq of the last packet sent, -1 before any
    last_peer_seq: int = 0  # ack to stamp on the next packet sent
    round_trip_cycles: int = -1  # own packets sent since the one the peer last acknowledged
    max_round_trip_cycles: int = 0
    _have_peer: bool = False

    def next_seq(self) -> int:
        """Advance and return the sequence number for the next packet sent."""
        self.own_seq = (self.own_seq + 1) & 0xFF
        self.sent += 1
        return self.own_seq

    def on_receive(self, seq: int, ack: int) -> None:
        """Account for a valid packet from the peer carrying ``seq`` and ``ack``."""
        self.received += 1
        if self._have_peer:
            gap = (seq - self.last_peer_seq) & 0xFF
            if gap == 0:
                self.duplicates += 1
                return
            if gap > 127:
                self.resyncs += 1
            else:
                self.lost += gap - 1
        self._have_peer = True
        self.last_peer_seq = seq
        if self.own_seq >= 0:
            rtt = (self.own_seq - ack) & 0xFF
            self.round_trip_cycles = rtt
            if rtt > self.max_round_trip_cycles:
                self.max_round_trip_cycles = rtt

    def on_error(self) -> None:
        """Count one datagram rejected as malformed."""
        self.malformed += 1

    def summary(self) -> str:
        """One line for status and logs."""
        return (
            f"sent {self.sent} recv {self.received} lost {self.lost} dup {self.duplicates} "
            f"resync {self.resyncs} bad {self.malformed} foreign {self.foreign} "
            f"rtt {self.round_trip_cycles} cyc"
        )


def encode_input(seq: int, ack: int, torque: np.ndarray, flags: int = 0,
                 token: int = DEFAULT_TOKEN) -> bytes:
    """Convenience: one torque packet as bytes (allocates; loops should reuse an InputPacket)."""
    pkt = InputPacket(token)
    pkt.torque[:] = torque
    pkt.flags = flags
    return pkt.to_bytes(seq, ack)
