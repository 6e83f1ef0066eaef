"""The lockstep resend timeout (``runtime.udp.ResendTimer``, RFC 6298) follows the measured
round trip, backs off on each expiry, and learns nothing from an answer to a resent datagram."""

from __future__ import annotations

import pytest

from runtime.udp import ResendTimer


def answer_after(timer: ResendTimer, t: float, rtt: float) -> float:
    timer.sent(t)
    timer.answered(t + rtt)
    return t + rtt


def test_steady_one_ms_round_trips_bring_the_timeout_down_to_its_floor() -> None:
    timer = ResendTimer(0.002, 0.01)
    assert timer.timeout_s == 0.01  # nothing measured yet: the longest wait
    t = 0.0
    for _ in range(200):
        t = answer_after(timer, t, 0.001)
    assert timer.srtt == pytest.approx(0.001)
    assert timer.timeout_s == pytest.approx(0.002)  # srtt + 4 rttvar ~ 1 ms, floored at 2


def test_jittery_round_trips_give_room_over_the_mean() -> None:
    timer = ResendTimer(0.0005, 0.05)
    t = 0.0
    for i in range(400):
        t = answer_after(timer, t, 0.001 if i % 2 else 0.003)
    assert 0.0019 < timer.srtt < 0.0021
    # mean deviation ~1 ms: the timeout sits ~4 ms over the mean, past the slow answers
    assert 0.004 < timer.timeout_s < 0.008


def test_each_expiry_doubles_the_wait_up_to_the_ceiling() -> None:
    timer = ResendTimer(0.002, 0.01)
    t = 0.0
    for _ in range(50):
        t = answer_after(timer, t, 0.001)
    timer.sent(t)
    waits = []
    for _ in range(4):
        timer.expired()
        waits.append(timer.timeout_s)
    assert waits == pytest.approx([0.004, 0.008, 0.01, 0.01])
    timer.sent(t + 1.0)  # the next state starts from the measured figure again
    assert timer.timeout_s == pytest.approx(0.002)


def test_an_answer_to_a_resent_datagram_is_no_sample() -> None:
    timer = ResendTimer(0.002, 0.01)
    t = 0.0
    for _ in range(50):
        t = answer_after(timer, t, 0.001)
    srtt = timer.srtt
    timer.sent(t)
    timer.expired()
    timer.answered(t + 0.5)  # which copy it answers is unknown: Karn's rule
    assert timer.srtt == srtt and timer.samples == 50


def test_bounds_are_checked() -> None:
    with pytest.raises(ValueError, match="0 < min <= max"):
        ResendTimer(0.02, 0.01)


def test_a_round_trip_grown_past_the_timeout_for_good_backs_it_off() -> None:
    timer = ResendTimer(0.001, 0.01)
    t = 0.0
    for _ in range(100):
        t = answer_after(timer, t, 0.0005)  # ~0.5 ms: the floor, 1 ms
    assert timer.timeout_s == pytest.approx(0.001)
    resent = 0
    for _ in range(30):  # now every answer takes 3 ms
        timer.sent(t)
        if timer.timeout_s < 0.003:  # it expires before the answer: sent again
            timer.expired()
            resent += 1
        timer.answered(t + 0.003)
        t += 0.003
    assert resent <= 9  # backed off after runs of three, not a resend on every cycle
    timer.sent(t)
    assert timer.timeout_s > 0.003
