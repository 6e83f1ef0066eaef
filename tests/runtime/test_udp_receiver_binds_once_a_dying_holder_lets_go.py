"""A UDP input whose port is still held (a killed predecessor being torn down) binds as soon
as the port is free, within ``bind_wait_s``; past it the error says who to look for."""

from __future__ import annotations

import socket
import threading
import time

import pytest

from runtime.errors import BusError
from runtime.udp import UdpReceiver


def held_port() -> tuple[socket.socket, tuple[str, int]]:
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind(("127.0.0.1", 0))
    return s, s.getsockname()


def test_the_port_is_taken_the_moment_its_holder_closes_it() -> None:
    holder, addr = held_port()
    threading.Timer(0.05, holder.close).start()
    t0 = time.monotonic()
    rx = UdpReceiver(addr, bind_wait_s=1.0)
    waited = time.monotonic() - t0
    try:
        assert 0.04 < waited < 0.5, waited
        tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        tx.sendto(b"hello", addr)
        time.sleep(0.01)
        assert rx.drain() == 1
        tx.close()
    finally:
        rx.close()


def test_a_port_still_held_past_the_wait_is_a_clear_error() -> None:
    holder, addr = held_port()
    try:
        with pytest.raises(BusError, match="another process already holds it"):
            UdpReceiver(addr, bind_wait_s=0.05)
    finally:
        holder.close()
