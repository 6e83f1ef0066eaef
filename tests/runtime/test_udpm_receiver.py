"""Our LCM receiver against LCM's own publisher: short and fragmented messages, regex
subscriptions, garbage, and the kernel filter that keeps unsubscribed channels away."""

from __future__ import annotations

import os
import random
import select
import socket
import time

import lcm
import pytest

from runtime.udpm import UdpmReceiver, channel_filter


@pytest.fixture
def url() -> str:
    return f"udpm://239.255.76.67:{random.randint(20000, 60000)}"


def _drain(rx: UdpmReceiver, seconds: float = 0.5) -> None:
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        select.select([rx.fileno()], [], [], 0.02)
        rx.drain()


def test_short_and_fragmented_messages_from_lcm_arrive_whole(url: str) -> None:
    rx = UdpmReceiver(url)
    got: list[tuple[str, bytes]] = []
    rx.subscribe("SHORT", lambda c, d: got.append((c, d)))
    rx.subscribe("BIG", lambda c, d: got.append((c, d)))
    tx = lcm.LCM(url + "?ttl=0")
    small = os.urandom(700)
    big = os.urandom(900_000)  # a depth frame's size: 14 fragments
    tx.publish("SHORT", small)
    tx.publish("BIG", big)
    _drain(rx)
    assert got == [("SHORT", small), ("BIG", big)]
    assert rx.bad == 0 and rx.fragments_dropped == 0


def test_regex_subscriptions_match_whole_channel_names(url: str) -> None:
    rx = UdpmReceiver(url)
    got: list[str] = []
    rx.subscribe("NETWORK_.*", lambda c, d: got.append(c))
    tx = lcm.LCM(url + "?ttl=0")
    for ch in ("NETWORK_CASSIE_STATE", "CASSIE_STATE", "XNETWORK_A", "NETWORK_MPFC_PLAN"):
        tx.publish(ch, b"x")
    _drain(rx)
    assert got == ["NETWORK_CASSIE_STATE", "NETWORK_MPFC_PLAN"]


def test_the_kernel_drops_channels_nobody_here_subscribed_to(url: str) -> None:
    rx = UdpmReceiver(url)
    got: list[str] = []
    rx.subscribe("CASSIE_STATE", lambda c, d: got.append(c))
    rx.subscribe("AB", lambda c, d: got.append(c))
    tx = lcm.LCM(url + "?ttl=0")
    # names sharing prefixes with the subscribed ones, and one message that is fragmented
    for ch in ("CASSIE_STATEX", "CASSIE_STAT", "ABC", "A", "OSC_TORQUE", "CASSIE_STATE", "AB"):
        tx.publish(ch, b"payload")
    tx.publish("DEPTH", os.urandom(300_000))
    _drain(rx)
    assert got == ["CASSIE_STATE", "AB"]
    # the five unwanted short messages never reached the socket: only the two wanted ones
    # (and the fragments of the long message, which the first fragment's name rules out)
    assert rx.received == 2 and rx.bad == 0


def test_garbage_on_the_port_is_counted_not_raised(url: str) -> None:
    rx = UdpmReceiver(url, filtered=False)
    got: list[bytes] = []
    rx.subscribe("OK", lambda c, d: got.append(d))
    port = int(url.rsplit(":", 1)[1])
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_TTL, 0)
    for junk in (b"", b"abc", b"LC02\x00\x00\x00\x01" + b"A" * 100, b"LC03" + b"\x00" * 30,
                 os.urandom(200)):
        s.sendto(junk, ("239.255.76.67", port))
    lcm.LCM(url + "?ttl=0").publish("OK", b"fine")
    _drain(rx)
    assert got == [b"fine"]
    assert rx.bad >= 4


def _states_through(rx: UdpmReceiver, url: str, second_half: bool) -> tuple[list[int], list[int]]:
    """Publish 2 kHz states across the wrap of utime's low 32 bits (71.6 min of sim time) to
    ``rx`` subscribed with 1 ms slot thinning; (utimes received, utimes sent)."""
    from lcmtypes import robot_state_t

    got: list[int] = []
    rx.subscribe("CASSIE_STATE", lambda c, d: got.append(robot_state_t.decode(d).header.utime),
                 slot_us=1000, second_half=second_half)
    tx = lcm.LCM(url + "?ttl=0")
    utimes = [2**32 - 3000 + 500 * k for k in range(20)]
    for u in utimes:
        m = robot_state_t()
        m.header.utime = u
        tx.publish("CASSIE_STATE", m.encode())
    _drain(rx)
    return got, utimes


def test_the_kernel_thins_a_rate_limited_channel_to_the_first_half_of_each_slot(url: str):
    rx = UdpmReceiver(url)
    got, utimes = _states_through(rx, url, second_half=False)
    assert got == utimes[0::2]  # every other one, none twice, the alternation kept
    assert rx.received == 10


def test_the_kernel_passes_the_other_half_of_each_slot_to_a_loop_that_fills_it_in(url: str):
    rx = UdpmReceiver(url)
    got, utimes = _states_through(rx, url, second_half=True)
    assert got == utimes[1::2]  # exactly the states the first-half loop does not get


def test_a_filter_program_accepts_exactly_the_names_it_was_built_for() -> None:
    prog = channel_filter({"CASSIE_STATE": None, "OSC_TORQUE": 1000})
    # magic checks, 2 instructions per 4/2/1-byte compare of "name\0", and the two returns
    assert prog[-2][0] == 0x06 and prog[-1] == (0x06, 0, 0, 0)
    assert all(0 <= jt <= 255 and 0 <= jf <= 255 for _, jt, jf, _ in prog)
