"""Who runs a process now: a robust, process-shared mutex that its running copy holds and its
standby waits on, so the standby learns of a crash the moment it happens.

A kill -9 of the torque bridge in real time sometimes knocked Cassie over: the target PC
zeroes its torques 10 ms after the last packet, and the standby answered 50-60 ms after the
kill (measured, ``zero_torque_steps`` 102-118 per kill). Most of that is the kernel, not the
supervisor: a killed process with ~550 MB locked in memory (``mlockall``) takes ~30 ms to
unmap it, and only then does its exit show (``pidfd``, ``SIGCHLD``, its sockets closing).
A robust mutex is released earlier: the kernel walks a dying thread's robust-futex list
before it tears the address space down (``mm_release``), and wakes a waiter with
``EOWNERDEAD`` (pthread_mutexattr_setrobust(3)).

So each process with a standby holds its launch's lock (``/dev/shm/cassie-<token>-<name>.alive``,
made by the supervisor) from a keeper thread for its whole life; the standby, once set up,
waits on it in a thread. ``EOWNERDEAD``: the running copy died; the standby now holds the lock
and takes over at once, without waiting for the supervisor's ``go`` (which comes later and
changes nothing). An ordered exit unlocks first (``release``), and a waiter that gets the lock
that way gives it back and goes on waiting for ``go``: a process that finished, or was
stopped, is not taken over. The supervisor ends a standby before it stops its process.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import errno
import logging
import mmap
import os
import threading
from pathlib import Path

from runtime.checkpoint import shm_dir
from runtime.pairing import TOKEN_ENV

log = logging.getLogger(__name__)

_MUTEX_BYTES = 64  # sizeof(pthread_mutex_t) is 40 on x86-64 glibc, 48 on aarch64
_ATTR_BYTES = 16  # sizeof(pthread_mutexattr_t): 4 / 8
_PTHREAD_PROCESS_SHARED = 1
_PTHREAD_MUTEX_ROBUST = 1

_NAMES = ("pthread_mutex_lock", "pthread_mutex_unlock", "pthread_mutex_consistent",
          "pthread_mutex_init", "pthread_mutexattr_init", "pthread_mutexattr_setpshared",
          "pthread_mutexattr_setrobust")


def _load() -> ctypes.CDLL | None:
    """The C library with the robust-mutex calls (glibc >= 2.34 has them in libc, older ones
    in libpthread); None where neither has them: no succession lock, standbys wait for the
    supervisor's ``go`` as before."""
    for name in ("c", "pthread"):
        path = ctypes.util.find_library(name)
        if path is None:
            continue
        try:
            lib = ctypes.CDLL(path, use_errno=True)
            for fn in _NAMES:
                f = getattr(lib, fn)
                f.argtypes = [ctypes.c_void_p] + (
                    [ctypes.c_int] if fn.startswith("pthread_mutexattr_set") else
                    [ctypes.c_void_p] if fn == "pthread_mutex_init" else [])
                f.restype = ctypes.c_int
            return lib
        except (OSError, AttributeError):
            continue
    return None


_libc = _load()


def lock_path(process: str, token: int | str | None = None) -> Path | None:
    """The lock of ``process`` in this launch (None outside a supervised launch)."""
    token = os.environ.get(TOKEN_ENV) if token is None else token
    if token is None or _libc is None or not shm_dir().is_dir():
        return None
    return shm_dir() / f"cassie-{token}-{process}.alive"


def _mapped(path: Path) -> tuple[mmap.mmap, int]:
    """The file's first page mapped shared, and the address of the mutex in it."""
    fd = os.open(path, os.O_RDWR)
    try:
        mem = mmap.mmap(fd, _MUTEX_BYTES)
    finally:
        os.close(fd)
    return mem, ctypes.addressof(ctypes.c_char.from_buffer(mem))  # (the map stays open)


def create_lock(path: Path) -> None:
    """Make ``path`` a fresh robust, process-shared mutex, unlocked (the supervisor, before it
    starts the process; a file left from another launch is replaced)."""
    tmp = path.with_suffix(".tmp")
    fd = os.open(tmp, os.O_RDWR | os.O_CREAT | os.O_TRUNC, 0o600)
    try:
        os.ftruncate(fd, _MUTEX_BYTES)
    finally:
        os.close(fd)
    mem, addr = _mapped(tmp)
    assert _libc is not None  # (lock_path gave no path without it)
    attr = ctypes.create_string_buffer(_ATTR_BYTES)
    for rc in (_libc.pthread_mutexattr_init(attr),
               _libc.pthread_mutexattr_setpshared(attr, _PTHREAD_PROCESS_SHARED),
               _libc.pthread_mutexattr_setrobust(attr, _PTHREAD_MUTEX_ROBUST),
               _libc.pthread_mutex_init(addr, attr)):
        if rc:
            raise OSError(rc, f"robust mutex in {tmp}: {os.strerror(rc)}")
    del addr
    mem.close()
    os.replace(tmp, path)  # whole: an opener never sees a half-made mutex


class Succession:
    """This process's hold on its lock. ``hold()``: take it (a running copy); ``watch()``: wait
    for it (a standby), with ``crashed`` set when the holder died. One keeper thread takes
    the lock and keeps it until ``release()`` (the owner of a robust mutex is a thread: the
    thread must live as long as the hold)."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self._mem, self._addr = _mapped(path)
        self.crashed = threading.Event()  # the holder died: take over
        self.ended = threading.Event()  # watch(): the holder stopped in order; hold(): held
        self._release = threading.Event()
        self._thread: threading.Thread | None = None
        self.error = ""  # why the lock could not be used, if it could not

    @classmethod
    def for_process(cls, process: str) -> Succession | None:
        """The lock of ``process`` in this launch, if the supervisor made one."""
        path = lock_path(process)
        if path is None or not path.exists():
            return None
        try:
            return cls(path)
        except OSError as exc:
            log.warning("%s: no succession lock (%s): a standby learns of a crash only from "
                        "the supervisor", process, exc)
            return None

    def _lock(self) -> int:
        rc = _libc.pthread_mutex_lock(self._addr)
        if rc == errno.EOWNERDEAD:  # the holder died holding it: ours now, made whole
            _libc.pthread_mutex_consistent(self._addr)
        elif rc:
            raise OSError(rc, f"locking {self.path}: {os.strerror(rc)}")
        return rc

    def _keep(self, watching: bool, wake_fd: int) -> None:
        try:
            rc = self._lock()
        except OSError as exc:  # a broken lock (ENOTRECOVERABLE...): run without it
            self.error = str(exc)
            log.warning("succession lock %s unusable (%s): a standby learns of a crash only "
                        "from the supervisor", self.path, exc)
            self.ended.set()
            if wake_fd >= 0:
                os.write(wake_fd, b"e")
            return
        if watching and rc != errno.EOWNERDEAD:
            _libc.pthread_mutex_unlock(self._addr)  # stopped in order: not ours to take over
            self.ended.set()
            os.write(wake_fd, b"e")
            return
        (self.crashed if watching else self.ended).set()
        if wake_fd >= 0:
            os.write(wake_fd, b"c")
        self._release.wait()
        _libc.pthread_mutex_unlock(self._addr)

    def hold(self, timeout_s: float = 5.0) -> bool:
        """Take the lock for this (running) copy; False if another holds it past the
        timeout (a copy already running: the caller should not run)."""
        self._start(False, -1)
        return self.ended.wait(timeout_s)  # (True too when the lock is broken: run without)

    def watch(self, wake_fd: int) -> None:
        """Wait for the lock in the background (a standby); a byte on ``wake_fd`` when it
        comes: ``crashed`` set (take over, the lock is held) or ``ended`` (given back)."""
        self._start(True, wake_fd)

    def _start(self, watching: bool, wake_fd: int) -> None:
        self._thread = threading.Thread(target=self._keep, args=(watching, wake_fd),
                                        name="succession", daemon=True)
        self._thread.start()

    def release(self) -> None:
        """An ordered exit: give the lock back, so the standby does not take over."""
        self._release.set()
        if self._thread is not None:
            self._thread.join(1.0)
