"""Loop accounting: a tick longer than the period or skipped slots count as overruns, and a
window of sim time advancing slower than the wall clock is flagged (status bit, log, status)."""

from __future__ import annotations

import logging

import pytest

from runtime.cassie_packets import STATUS_SLOWER_THAN_REALTIME, OutputPacket
from sim.target_pc import LoopStats, TargetPC, make_core
from sim.terrain import flat


def test_overruns_count_long_ticks_and_skipped_slots() -> None:
    s = LoopStats(period_s=0.0005)
    s.record(0.0002, 0.0005, wall=0.0)
    s.record(0.0007, 0.0010, wall=0.0005)  # ran past its slot
    s.record(0.0001, 0.0015, skipped=3, wall=0.0025)  # the loop skipped three slots
    assert s.overruns == 4 and s.max_task_s == 0.0007


def test_running_slower_than_real_time_is_reported(caplog: pytest.LogCaptureFixture) -> None:
    tpc = TargetPC(make_core(flat()), "realtime")
    stats = tpc.stats
    sim_t = 0.0
    wall = 0.0
    with caplog.at_level(logging.WARNING, logger="sim.target_pc"):
        for _ in range(3000):  # 1.5 s of sim time over 2.0 s of wall time
            sim_t += 0.0005
            wall += 0.0005 / 0.75
            stats.record(0.0001, sim_t, wall=wall)
    assert stats.slower_than_realtime and abs(stats.rtf - 0.75) < 0.01
    assert any("slower than real time" in r.getMessage() for r in caplog.records)
    out = OutputPacket().decode(bytes(tpc.encode_state()))
    assert out.status & STATUS_SLOWER_THAN_REALTIME
    assert "SLOWER-THAN-REALTIME" in tpc.summary()
    for _ in range(2500):  # back to real time
        sim_t += 0.0005
        wall += 0.0005
        stats.record(0.0001, sim_t, wall=wall)
    assert not stats.slower_than_realtime
    out.decode(bytes(tpc.encode_state()))
    assert not out.status & STATUS_SLOWER_THAN_REALTIME
