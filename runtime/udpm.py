"""Receiving LCM's UDP multicast ourselves: the same wire format, without LCM's receive thread.

LCM's C library reads its socket in a thread of its own and hands each message to the caller
through a pipe; on this machine (a VM where every thread wake-up goes through the hypervisor)
that hand-off costs ~30 us of CPU per message, while reading the multicast socket directly in
the loop's own thread costs ~4 us. A control loop at 2 kHz that subscribes to a 2 kHz channel
pays the difference on every tick, so the bus receives with this module and publishes with
LCM (``lcm.LCM.publish``: one ``sendmsg``, ~1 us). The wire format is LCM's ``udpm`` protocol
(``lcm/udpm_util.h``): a short message is one datagram ``"LC02" seqno channel\\0 payload``; a
long one is fragments ``"LC03" seqno msg_size fragment_offset fragment_no fragments_in_msg``,
the first carrying ``channel\\0``. Anything else on the port is counted and dropped.

A receiver that only wants some channels asks the kernel to drop the rest (a classic BPF
socket filter matching the channel name of short messages): the datagrams of a busy
domain that it does not subscribe to never wake it, nor cost it a read.
"""

from __future__ import annotations

import ctypes
import re
import select
import socket
import struct
from collections import OrderedDict
from collections.abc import Callable
from typing import Any

from runtime.route import multicast_group

MAGIC_SHORT = 0x4C433032  # "LC02"
MAGIC_LONG = 0x4C433033  # "LC03"
_SHORT = struct.Struct(">II")
_LONG = struct.Struct(">IIIIHH")
MAX_CHANNEL = 63  # LCM_MAX_CHANNEL_NAME_LENGTH
MAX_MESSAGE = 1 << 28  # LCM_MAX_MESSAGE_SIZE
MAX_PENDING_BYTES = 1 << 24  # fragment buffers in flight (LCM's MAX_FRAG_BUF_TOTAL_SIZE)
MAX_PENDING = 1000  # messages being reassembled at once (LCM's MAX_NUM_FRAG_BUFS)
IP_MULTICAST_ALL = 49  # Linux: 0 = only the groups this socket joined
SO_ATTACH_FILTER = 26
SO_TIMESTAMPNS = 35  # (SCM_TIMESTAMPNS: a struct timespec of the arrival, CLOCK_REALTIME)
SO_RXQ_OVFL = 40  # ancillary uint32: datagrams the kernel dropped on this socket (buffer full)
_TIMESPEC = struct.Struct("@qq")
SO_DETACH_FILTER = 27
_UDP_HEADER = 8  # a UDP socket's filter sees the UDP header first, then LCM's datagram


class _SockFilter(ctypes.Structure):
    _fields_ = [("code", ctypes.c_uint16), ("jt", ctypes.c_uint8), ("jf", ctypes.c_uint8),
                ("k", ctypes.c_uint32)]


class _SockFprog(ctypes.Structure):
    _fields_ = [("len", ctypes.c_uint16), ("filter", ctypes.POINTER(_SockFilter))]


_LD_W, _LD_H, _LD_B = 0x20, 0x28, 0x30  # BPF_LD | size | BPF_ABS
_JEQ = 0x15  # BPF_JMP | BPF_JEQ | BPF_K
_RET = 0x06  # BPF_RET | BPF_K


_MOD_K = 0x94  # BPF_ALU | BPF_MOD | BPF_K
_JGE = 0x35  # BPF_JMP | BPF_JGE | BPF_K
_JA = 0x05  # BPF_JMP | BPF_JA
_SKF_AD_RANDOM = 0xFFFFF000 + 56  # SKF_AD_OFF + SKF_AD_RANDOM: a random u32 in A


def attach_filter(sock: socket.socket, prog: list[tuple[int, int, int, int]]) -> Any:
    """Attach the classic BPF program ``prog`` ((code, jt, jf, k) each) to ``sock``; returns
    what must be kept alive as long as it is attached."""
    arr = (_SockFilter * len(prog))(*[_SockFilter(*ins) for ins in prog])
    fprog = _SockFprog(len(prog), arr)
    sock.setsockopt(socket.SOL_SOCKET, SO_ATTACH_FILTER,
                    ctypes.string_at(ctypes.addressof(fprog), ctypes.sizeof(fprog)))
    return arr, fprog


def random_drop_filter(ratio: float) -> list[tuple[int, int, int, int]]:
    """A program that drops each datagram with probability ``ratio`` (the kernel's random
    number, SKF_AD_RANDOM): a lossy link, emulated where the socket receives, for fault tests
    on machines without netfilter or netem."""
    if not 0.0 <= ratio <= 1.0:
        raise ValueError(f"a drop ratio is in [0, 1], got {ratio!r}")
    threshold = min(round(ratio * 2**32), 2**32 - 1)
    return [(_LD_W, 0, 0, _SKF_AD_RANDOM),
            (_JGE, 0, 1, threshold),  # random >= threshold: keep it, else drop
            (_RET, 0, 0, 0xFFFFFFFF),
            (_RET, 0, 0, 0)]


def channel_filter(
    channels: dict[str, int | tuple[int, bool] | None],
) -> list[tuple[int, int, int, int]]:
    """A classic BPF program that accepts LCM short messages on ``channels`` (exact names)
    and every fragment of a long message (the first fragment names the channel, the others
    cannot be judged), and drops everything else.

    A channel given a slot (us) is also thinned in the kernel: only messages whose
    ``header.utime`` falls in the first half of a slot (``utime mod slot < slot / 2``) pass,
    so a 1 kHz loop on 2 kHz states is woken by every other state only. (The low 32 bits of
    the big-endian utime, at its fixed place after the channel name and the type's
    fingerprint; they stay in step with the full utime for any slot dividing 2^32 us, and
    for others still alternate the same way.) A slot given as ``(slot, True)`` passes the
    second half instead: the messages such a loop skips, for a loop that fills them in.
    """
    code: list[list[int | str]] = []  # [op, jt, jf, k]; jt/jf/k may name a label
    labels: dict[str, int] = {}
    code.append([_LD_W, 0, 0, _UDP_HEADER])
    code.append([_JEQ, "accept", 0, MAGIC_LONG])
    code.append([_JEQ, 0, "reject", MAGIC_SHORT])
    names = sorted(channels)
    for b, name in enumerate(names):
        labels[f"ch{b}"] = len(code)
        nxt = f"ch{b + 1}" if b + 1 < len(names) else "reject"
        data = name.encode("ascii") + b"\0"
        off = 0
        while off < len(data):  # compare the name and its NUL terminator, 4/2/1 bytes at a time
            n = 4 if len(data) - off >= 4 else (2 if len(data) - off >= 2 else 1)
            op = {4: _LD_W, 2: _LD_H, 1: _LD_B}[n]
            code.append([op, 0, 0, _UDP_HEADER + 8 + off])
            code.append([_JEQ, 0, nxt, int.from_bytes(data[off : off + n], "big")])
            off += n
        spec = channels[name]
        slot, second = spec if isinstance(spec, tuple) else (spec, False)
        if slot:
            utime_low = _UDP_HEADER + 8 + len(data) + 8 + 4
            code.append([_LD_W, 0, 0, utime_low])
            code.append([_MOD_K, 0, 0, int(slot)])
            if second:
                code.append([_JGE, 0, "reject", int(slot) // 2])
            else:
                code.append([_JGE, "reject", 0, int(slot) // 2])
        code.append([_JA, 0, 0, "accept"])
    labels["accept"] = len(code)
    code.append([_RET, 0, 0, 0xFFFFFFFF])
    labels["reject"] = len(code)
    code.append([_RET, 0, 0, 0])
    out = []
    for i, (op, jt, jf, k) in enumerate(code):
        def rel(x: int | str, i: int = i) -> int:
            if isinstance(x, int):
                return x
            d = labels[x] - i - 1
            if not 0 <= d <= 255:
                raise ValueError("too many channels for one socket filter")
            return d
        if op == _JA:
            out.append((op, 0, 0, labels[str(k)] - i - 1))
        else:
            out.append((int(op), rel(jt), rel(jf), int(k)))  # type: ignore[arg-type]
    return out


Handler = Callable[[str, bytes], None]


class _Partial:
    """A long message being reassembled from its fragments."""

    __slots__ = ("channel", "data", "remaining")

    def __init__(self, size: int, fragments: int) -> None:
        self.data = bytearray(size)
        self.remaining = fragments
        self.channel = ""


#: SO_RCVBUFFORCE (linux/socket.h): a receive buffer past net.core.rmem_max, for root
_SO_RCVBUFFORCE = getattr(socket, "SO_RCVBUFFORCE", 33)


def _set_recv_buf(s: socket.socket, size: int) -> None:
    """The receive buffer asked for: ``SO_RCVBUF`` is silently capped at net.core.rmem_max
    (4 MB here), which made the logger drop 358,731 datagrams of depth frames in a 25 s
    lockstep perception run; past the cap with ``SO_RCVBUFFORCE`` where allowed (root,
    CAP_NET_ADMIN), else as much as the cap gives."""
    try:
        s.setsockopt(socket.SOL_SOCKET, _SO_RCVBUFFORCE, size)
    except OSError:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, size)


class UdpmReceiver:
    """One LCM ``udpm://GROUP:PORT`` domain, read in the caller's thread.

    ``subscribe`` takes a channel name (exact, the fast path) or a regex (matched in full, as
    LCM does); ``drain`` reads every datagram waiting in the socket and calls the handlers of
    each complete message. Non-blocking: the caller waits on ``fileno()`` (select) itself.
    """

    def __init__(self, url: str, recv_buf_size: int | None = 2 << 20,
                 filtered: bool = True, timestamps: bool = False) -> None:
        """``filtered``: let the kernel drop the channels nobody subscribed to here.
        ``timestamps``: note each datagram's kernel arrival time (``last_recv_utime``, wall
        clock, us), so a reader that drains in batches still logs when each message came."""
        group, port = multicast_group(url)
        self.url = url
        s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM, socket.IPPROTO_UDP)
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        if hasattr(socket, "SO_REUSEPORT"):
            s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEPORT, 1)
        if recv_buf_size:
            _set_recv_buf(s, recv_buf_size)
        s.bind(("", port))
        try:
            s.setsockopt(socket.IPPROTO_IP, IP_MULTICAST_ALL, 0)
        except OSError:
            pass
        mreq = struct.pack("4s4s", socket.inet_aton(group), socket.inet_aton("0.0.0.0"))
        s.setsockopt(socket.IPPROTO_IP, socket.IP_ADD_MEMBERSHIP, mreq)
        s.setblocking(False)
        self.sock = s
        self.timestamps = timestamps
        self.last_recv_utime = 0
        self.kernel_dropped = 0  # (timestamps mode) datagrams lost to a full socket buffer
        if timestamps:
            s.setsockopt(socket.SOL_SOCKET, SO_TIMESTAMPNS, 1)
            try:
                s.setsockopt(socket.SOL_SOCKET, SO_RXQ_OVFL, 1)
            except OSError:
                pass
        # "is a datagram waiting?" without a failed read: Python raises on EAGAIN, and an
        # exception per drain costs more on this VM than one poll(0)
        self._ready = select.poll()
        self._ready.register(s.fileno(), select.POLLIN)
        self._buf = bytearray(65536)
        self._view = memoryview(self._buf)
        self._exact: dict[str, list[Handler]] = {}
        #: channel -> kernel-side slot thinning (us, and whether the second half passes)
        self._slots: dict[str, tuple[int, bool]] = {}
        self._patterns: list[tuple[re.Pattern[str], Handler]] = []
        self._route: dict[str, list[Handler]] = {}  # channel -> handlers, memoised
        self._partial: OrderedDict[tuple[Any, int], _Partial] = OrderedDict()
        self._ignored: OrderedDict[tuple[Any, int], None] = OrderedDict()  # unwanted long msgs
        self._pending_bytes = 0
        self._filtered = filtered
        self._prog: Any = None  # the attached filter program (kept alive with the socket)
        self.received = 0  # complete messages
        self.bad = 0  # datagrams that are not LCM, or inconsistent fragments
        self.fragments_dropped = 0  # long messages given up (a fragment never came)

    def fileno(self) -> int:
        return self.sock.fileno()

    def subscribe(self, channel_or_regex: str, handler: Handler,
                  slot_us: int | None = None, second_half: bool = False) -> None:
        """Call ``handler(channel, payload)`` for every message on a matching channel.
        ``slot_us`` (an exact channel whose type starts with a header): let the kernel pass
        only messages in the first half of each slot of that many microseconds (the second
        half with ``second_half``)."""
        if re.fullmatch(r"[A-Za-z0-9_]+", channel_or_regex):
            self._exact.setdefault(channel_or_regex, []).append(handler)
            if slot_us:
                self._slots[channel_or_regex] = (int(slot_us), second_half)
        else:
            self._patterns.append((re.compile(channel_or_regex), handler))
        self._route.clear()
        self._update_filter()

    def _update_filter(self) -> None:
        """Attach the channel filter (none once a regex subscription wants everything)."""
        if not self._filtered:
            return
        if self._patterns:
            if self._prog is not None:
                self.sock.setsockopt(socket.SOL_SOCKET, SO_DETACH_FILTER, 0)
                self._prog = None
            return
        try:
            prog = channel_filter({c: self._slots.get(c) for c in self._exact})
        except ValueError:  # more channels than one program can hold: take everything
            return
        self._prog = attach_filter(self.sock, prog)

    def unsubscribe(self, handler: Handler) -> None:
        for hs in self._exact.values():
            while handler in hs:
                hs.remove(handler)
        self._patterns = [(p, h) for p, h in self._patterns if h is not handler]
        self._route.clear()

    def _handlers(self, channel: str) -> list[Handler]:
        hs = self._route.get(channel)
        if hs is None:
            hs = list(self._exact.get(channel, ()))
            hs += [h for p, h in self._patterns if p.fullmatch(channel)]
            if len(self._route) < 4096:
                self._route[channel] = hs
        return hs

    def drain(self, known_ready: bool = False) -> int:
        """Read every waiting datagram; returns the number of complete messages handled.
        ``known_ready``: the caller's poll just said a datagram is there."""
        n = 0
        sock, buf, view, ready = self.sock, self._buf, self._view, self._ready.poll
        stamped = self.timestamps
        while known_ready or ready(0):
            known_ready = False
            try:
                if stamped:
                    size, anc, _, sender = sock.recvmsg_into([buf], 64)
                    for level, kind, data in anc:
                        if level != socket.SOL_SOCKET:
                            continue
                        if kind == SO_TIMESTAMPNS:
                            sec, nsec = _TIMESPEC.unpack_from(data)
                            self.last_recv_utime = sec * 1_000_000 + nsec // 1000
                        elif kind == SO_RXQ_OVFL and len(data) >= 4:
                            self.kernel_dropped = int.from_bytes(data[:4], "little")
                else:
                    size, sender = sock.recvfrom_into(buf)
            except OSError:  # (BlockingIOError: another reader took it)
                return n
            if size < 8:
                self.bad += 1
                continue
            magic = _SHORT.unpack_from(buf)[0]
            if magic == MAGIC_SHORT:
                end = buf.find(0, 8, min(size, 8 + MAX_CHANNEL + 1))
                if end < 0:
                    self.bad += 1
                    continue
                channel = buf[8:end].decode("ascii", "replace")
                hs = self._handlers(channel)
                self.received += 1
                n += 1
                if hs:
                    data = bytes(view[end + 1 : size])
                    for h in hs:
                        h(channel, data)
            elif magic == MAGIC_LONG:
                done = self._fragment(view, size, sender)
                if done is not None:
                    channel, data = done
                    self.received += 1
                    n += 1
                    for h in self._handlers(channel):
                        h(channel, data)
            else:
                self.bad += 1
        return n

    def _fragment(self, view: memoryview, size: int, sender: Any) -> tuple[str, bytes] | None:
        if size < _LONG.size:
            self.bad += 1
            return None
        _, seqno, total, offset, frag_no, nfrags = _LONG.unpack_from(view)
        if total > MAX_MESSAGE or nfrags == 0:
            self.bad += 1
            return None
        start = _LONG.size
        key = (sender, seqno)
        if key in self._ignored:
            return None
        part = self._partial.get(key)
        if part is not None and len(part.data) != total:  # a stale message with that seqno
            self._drop(key)
            part = None
        channel = None
        if frag_no == 0:
            end = bytes(view[start : min(size, start + MAX_CHANNEL + 1)]).find(b"\0")
            if end < 0:
                self.bad += 1
                return None
            channel = bytes(view[start : start + end]).decode("ascii", "replace")
            start += end + 1
        if part is None:
            if channel is not None and not self._handlers(channel):
                # nobody here wants it (a depth frame on the laptop's bus, say): skip the rest
                # of its fragments without reassembling them
                self._ignored[key] = None
                if len(self._ignored) > 64:
                    self._ignored.popitem(last=False)
                return None
            part = _Partial(total, nfrags)
            self._partial[key] = part
            self._pending_bytes += total
            self._evict()
        if channel is not None:
            part.channel = channel
        n = size - start
        if offset + n > total:
            self.bad += 1
            self._drop(key)
            return None
        part.data[offset : offset + n] = view[start:size]
        part.remaining -= 1
        if part.remaining > 0:
            return None
        self._drop(key, complete=True)
        if not part.channel:
            self.bad += 1
            return None
        return part.channel, bytes(part.data)

    def _drop(self, key: tuple[Any, int], complete: bool = False) -> None:
        part = self._partial.pop(key, None)
        if part is not None:
            self._pending_bytes -= len(part.data)
            if not complete:
                self.fragments_dropped += 1

    def _evict(self) -> None:
        while self._partial and (
            self._pending_bytes > MAX_PENDING_BYTES or len(self._partial) > MAX_PENDING
        ):
            self._drop(next(iter(self._partial)))

    def close(self) -> None:
        try:
            self.sock.close()
        except OSError:
            pass
