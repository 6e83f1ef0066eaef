"""A UDP receiver with ``drop_ratio`` (``$CASSIE_UDP_LOSS``, the fault tests' lossy link) loses
that share of the datagrams in the kernel, before its socket sees them; a bad value of the
variable is a clear error that names it."""

from __future__ import annotations

import socket

import pytest

from runtime.errors import BusError
from runtime.udp import LOSS_ENV, UdpReceiver, loss_from_env


@pytest.mark.parametrize("ratio", [0.0, 0.05, 0.2])
def test_the_receiver_loses_about_the_share_asked(ratio: float) -> None:
    rx = UdpReceiver(("127.0.0.1", 0), policy="each", capacity=100_000, drop_ratio=ratio)
    port = rx.sock.getsockname()[1]
    tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    got = 0
    try:
        for k in range(20_000):
            tx.sendto(b"x" * 100, ("127.0.0.1", port))
            if k % 100 == 99:
                got += rx.drain()
        got += rx.drain()
    finally:
        rx.close()
        tx.close()
    lost = 1.0 - got / 20_000
    assert abs(lost - ratio) < 0.015, lost  # (binomial: sd 0.3 % at 20 %)


def test_a_bad_loss_value_names_the_variable(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv(LOSS_ENV, raising=False)
    assert loss_from_env() == 0.0
    monkeypatch.setenv(LOSS_ENV, "0.05")
    assert loss_from_env() == 0.05
    for bad in ("5%", "1.5", "-0.1", "nan"):
        monkeypatch.setenv(LOSS_ENV, bad)
        with pytest.raises(BusError, match=LOSS_ENV):
            loss_from_env()
