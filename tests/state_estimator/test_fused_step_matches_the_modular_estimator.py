"""The fused compiled step gives the estimates of the modular Python estimator it replaced.

Recorded robot-output packets of a scripted run (touchdowns, lift-offs, the ALIP filter on every
10th packet, R re-orthonormalised every 1000th), with a lost packet, a resent one, a NaN, an
out-of-range value and a short datagram mixed in, go through the estimator node three ways:
the fused step (the default), ``fused=False`` (the modular parts composed in Python, as before
the fused step) and, when git has it, the estimator package of commit 7028c65 (the last one
before the fused step). Every published message must carry the same integers and flags and the
same floats to 1e-12 (measured: q and v to the bit; the ALIP state within 3e-14, filterpy's
BLAS/LAPACK against the compiled loops; the contact force within one ulp, numpy's matmul
against a plain product sum): any term dropped or changed in the fused step fails this.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from processes.state_estimator.process import StateEstimatorNode
from runtime.cassie_packets import OutputPacket
from runtime.driver import NodeDriver

#: the commit whose estimator the fused step replaced
BASELINE = "7028c65"
FLOAT_TOL = {"rtol": 1e-12, "atol": 1e-12}


@pytest.fixture(scope="module")
def datagrams() -> list[bytes]:
    """2.5 s of the scripted ``steps`` motion (each leg lifted and set down), with faults."""
    from tools.testbed.estimator_motions import run_loop

    rec = run_loop("steps", 2.5)
    out = [bytes(p) for p in rec.packets]
    assert len(out) >= 5000
    bad = OutputPacket()
    bad.decode(out[1500])
    bad.joint_vel[2] = float("nan")
    nan = bad.to_bytes(bad.seq, bad.ack)
    bad.decode(out[2500])
    bad.imu_quat[:] = (2.0, 0.0, 0.0, 0.0)  # not a rotation: the range check
    far = bad.to_bytes(bad.seq, bad.ack)
    del out[1200]  # lost on the wire
    out.insert(1400, out[1399])  # resent (lockstep)
    out.insert(1500, nan)
    out.insert(2500, far)
    out.insert(3000, out[3000][:100])  # too short
    return out


def _run(node: Any, datagrams: list[bytes]) -> tuple[dict[str, list[Any]], Any]:
    """Every datagram through ``node``, one tick each; contact at 200 Hz as hw_config has it
    (the first state of each 5 ms of sim time)."""
    d = NodeDriver(node, output_rate_hz={"contact": 200.0})
    for raw in datagrams:
        assert d.tick(robot_output=raw)
    return d.sent, node


def _assert_same(a: dict[str, list[Any]], b: dict[str, list[Any]]) -> None:
    assert {r: len(m) for r, m in a.items()} == {r: len(m) for r, m in b.items()}
    for i, (mx, my) in enumerate(zip(a["contact"], b["contact"], strict=True)):
        assert (mx.header.utime, mx.in_contact) == (my.header.utime, my.in_contact), i
        np.testing.assert_allclose(mx.spring_deflection, my.spring_deflection, **FLOAT_TOL)
        np.testing.assert_allclose(mx.force_estimate, my.force_estimate, **FLOAT_TOL)
    for role in ("state", "network_state"):
        for i, (mx, my) in enumerate(zip(a[role], b[role], strict=True)):
            for f in ("num_positions", "num_velocities", "num_motors", "alip_stance",
                      "in_contact", "status", "target_status", "packet_seq", "packets_lost",
                      "packets_rejected"):
                assert getattr(mx, f) == getattr(my, f), (role, i, f)
            assert mx.header.utime == my.header.utime, (role, i)
            for f in ("q", "v", "motor_torque", "imu_accel", "alip_x", "alip_stance_pos"):
                np.testing.assert_allclose(getattr(mx, f), getattr(my, f), **FLOAT_TOL,
                                           err_msg=f"{role} {i}: {f}")


def test_fused_step_publishes_what_the_modular_estimator_does(datagrams):
    fused, node = _run(StateEstimatorNode(), datagrams)
    ref, ref_node = _run(StateEstimatorNode(fused=False), datagrams)
    _assert_same(ref, fused)
    # the run exercised what it should: both feet planted and lifted, the ALIP filter, faults
    states = fused["state"]
    assert {tuple(s.in_contact) for s in states} >= {(True, True), (True, False), (False, True)}
    assert {s.alip_stance for s in states} >= {0, 1}
    assert node.rejected == ref_node.rejected == 3
    assert node.link.lost == ref_node.link.lost == 1 and node.link.duplicates == 1
    assert any(s.status & 4 for s in states)  # the gap bit after the lost packet
    # and the filters' internal state agrees too
    a, b = node.estimator, ref_node.estimator
    np.testing.assert_allclose(a.filter.P, b.filter.P, rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(a.filter.d, b.filter.d, **FLOAT_TOL)
    assert list(a.filter.contact) == list(b.filter.contact)


def test_fused_update_matches_the_modular_update(datagrams):
    from processes.state_estimator.estimator import CassieEstimator

    fused, ref = CassieEstimator(), CassieEstimator(fused=False)
    pkt = OutputPacket()
    n = 0
    for raw in datagrams[:3000]:
        if len(raw) != len(pkt.buffer):
            continue
        try:
            pkt.decode(raw)
            ref.check(pkt)
        except ValueError:
            continue
        fused.check(pkt)
        alip = n % 10 == 0
        n += 1
        e, r = fused.update(pkt, alip=alip), ref.update(pkt, alip=alip)
        np.testing.assert_allclose(e.q, r.q, **FLOAT_TOL)
        np.testing.assert_allclose(e.v, r.v, **FLOAT_TOL)
        np.testing.assert_allclose(e.alip_x, r.alip_x, **FLOAT_TOL)
        assert (e.utime, e.status, e.alip_stance, e.in_contact) == (
            r.utime, r.status, r.alip_stance, r.in_contact)
    assert n > 2500


def test_fused_step_publishes_what_the_estimator_before_it_did(datagrams):
    from tools.benchmarks.estimator import baseline_node

    try:
        old = baseline_node(BASELINE)
    except SystemExit as exc:  # a clone without that commit (shallow, or an export)
        pytest.skip(str(exc))
    fused, _ = _run(StateEstimatorNode(), datagrams)
    before, _ = _run(old(), datagrams)
    _assert_same(before, fused)
