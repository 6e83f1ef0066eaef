"""The batcher in-process: deterministic messages in, a recording out, read back with the SDK."""

from __future__ import annotations

import itertools
import time
from pathlib import Path

import numpy as np
import pytest
import rerun as rr

from lcmtypes import robot_state_t, torque_command_t
from tests.dashboard import fake_stack
from tests.dashboard.rrd import Recording, read_rrd
from tools.dashboard.blueprint import build_blueprint, log_static
from tools.dashboard.channels import Channels
from tools.dashboard.convert import Batcher, pick_by_period, polygon_mask, reduce_max
from tools.dashboard.wire import fingerprint, read_headers

T0 = time.monotonic_ns()  # send times near now: others are taken for another host's clock


def _run(tmp_path: Path, batches: list[dict[str, list[bytes]]], skeleton: object = None,
         **kw: object) -> Recording:
    """The dashboard's static set-up (the robot's meshes too, with a meshed ``skeleton``) and
    its batcher over ``batches``, into a recording read back."""
    from tools.dashboard.robot import log_meshes

    path = tmp_path / "unit.rrd"
    rec = rr.RecordingStream("dashboard_unit_test")
    rec.save(path, default_blueprint=build_blueprint())
    log_static(rec)
    if skeleton is not None and skeleton.has_meshes:  # type: ignore[attr-defined]
        log_meshes(rec, skeleton)  # type: ignore[arg-type]
    b = Batcher(rec, Channels(), skeleton=skeleton, **kw)  # type: ignore[arg-type]
    for batch in batches:
        b.process(batch)
    b.process({}, flush=True)
    rec.flush()
    rec.disconnect()
    assert not b.errors, b.errors
    return read_rrd(path)


def _stack_batches(ticks: int, per_batch: int = 33, with_mask: bool = False
                   ) -> list[dict[str, list[bytes]]]:
    seqs: dict[str, int] = {}
    out = []
    for start in range(0, ticks, per_batch):
        msgs = [
            m for t in range(start, start + per_batch) for m in fake_stack.messages(t, with_mask)
        ]
        out.append(fake_stack.stamp_all(msgs, T0 + start * 1_000_000, 10_000, seqs))
    return out


def test_hop_latency_is_the_send_time_difference_of_matching_utimes(tmp_path: Path) -> None:
    states, torques = [], []
    for k in range(20):
        s, t = fake_stack.state(1000 * (k + 1)), fake_stack.torque(1000 * (k + 1))
        s.header.send_mono_ns = T0 + k * 10_000_000  # 100 Hz: below the series' point rate
        t.header.send_mono_ns = s.header.send_mono_ns + 300_000 + 10_000 * k  # 0.30..0.49 ms
        states.append(s.encode())
        torques.append(t.encode())
    orphan = fake_stack.torque(999_999)  # no state with this utime: no latency row
    orphan.header.send_mono_ns = T0
    rec = _run(tmp_path, [{"CASSIE_STATE": states, "OSC_TORQUE": [*torques, orphan.encode()]}])
    lat = rec.scalars("/latency/state_to_torque_ms")
    assert lat == pytest.approx([0.30 + 0.01 * k for k in range(20)], abs=1e-9)
    assert rec.timelines["/latency/state_to_torque_ms"] == {"sim_time", "wall_time"}


def test_whole_stack_writes_every_view_entity(tmp_path: Path) -> None:
    rec = _run(tmp_path, _stack_batches(1000))
    for proc, loop in fake_stack.LOOPS:
        for metric in ("rate_hz", "exec_ms", "lateness_ms", "deadline_misses"):
            assert f"/timing/{metric}/{proc}/{loop}" in rec.rows, (metric, proc, loop)
    exec_rows = rec.column("/timing/exec_ms/osc/tick", "Scalars:scalars")
    # p50, p99, max per row, and the loop's deadline beside them
    assert exec_rows and all(len(r) == 4 and r[3] == 0.5 for r in exec_rows)
    for hop in ("state_to_torque", "sensor_to_applied", "state_to_plan", "depth_to_map",
                "map_to_footholds", "depth_to_footholds"):
        vals = rec.scalars(f"/latency/{hop}_ms")
        assert vals and all(0 < v < 50 for v in vals), hop
    assert rec.scalars("/mpfc/solve_ms")[0] == pytest.approx(2.0)
    lanes = rec.column("/supervisor/states/s3", "StateChange:state")
    assert [x[0] for x in lanes] == ["starting", "ready", "backoff"]
    # the supervisor has no sim time: its rows (ticks 0, 250, 750) take the newest sim time of
    # their batch (33 ticks a batch: ticks 32, 263, 758)
    sim = rec.column("/supervisor/states/s3", "sim_time")
    assert [t // 1000 for t in sim] == [1_000_000 + 1000 * k for k in (32, 263, 758)]
    gait = [x[0] for x in rec.column("/mpfc/gait", "StateChange:state")]
    assert set(gait) == {"left stance", "right stance"} and len(gait) >= 3  # only changes
    assert all(a != b for a, b in itertools.pairwise(gait))
    steps = rec.column("/world/plan/footsteps", "Points3D:positions")
    assert steps and len(steps[-1]) == 3
    polys = rec.column("/world/footholds", "LineStrips3D:strips")
    assert polys and len(polys[-1]) == 2 and len(polys[-1][0]) == 5  # closed quads
    assert "/maps/elevation" in rec.rows and "/world/elevation_map" in rec.rows
    # no skeleton in this test: the robot is the pelvis pose and the ground-truth feet
    assert rec.rows["/world/robot/pelvis"] >= 25  # 30 Hz of ~1 s of sim time
    assert "/world/robot/feet" in rec.rows
    assert rec.blueprints == 1


def test_s3_mask_from_a_map_layer(tmp_path: Path) -> None:
    rec = _run(tmp_path, _stack_batches(100, with_mask=True))
    bufs = rec.column("/maps/s3_mask", "SegmentationImage:buffer")
    assert bufs
    n = fake_stack.MAP_N
    mask = np.asarray(bufs[-1], np.uint8).reshape(n, n)[::-1]  # back to rows = +y
    assert (mask[:, n // 2] == 0).all()  # the step edge: unsafe
    assert (mask[10:, : n // 2 - 2] == 1).all()  # flat ground: safe
    assert (mask[:3, :3] == 2).all()  # NaN cells: unknown


def test_s3_mask_derived_from_footholds_without_a_layer(tmp_path: Path) -> None:
    rec = _run(tmp_path, _stack_batches(100, with_mask=False))
    bufs = rec.column("/maps/s3_mask", "SegmentationImage:buffer")
    n = fake_stack.MAP_N
    mask = np.asarray(bufs[-1], np.uint8).reshape(n, n)[::-1]
    # the polygons span |y| <= 0.9 and x0 - 0.9 .. x0 + 0.9 but for a gap around x0; the map
    # (5 cm cells) spans +-0.975 around (x0, 0): 36 rows x (36 - 3) columns are inside, less
    # cell (2, 2), which has no elevation (unknown)
    assert (mask == 1).sum() == 36 * 33 - 1
    assert mask[20, 5] == 1 and mask[20, 30] == 1  # on either polygon
    assert mask[20, 20] == 0 and mask[39, 20] == 0  # in the gap; beyond |y| = 0.9
    assert (mask[:3, :3] == 2).all()  # unknown cells


def test_no_per_message_log_calls(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    calls: list[str] = []
    real_log = rr.RecordingStream.log

    def counting_log(self: rr.RecordingStream, path: str, *a: object, **kw: object) -> None:
        calls.append(path)
        real_log(self, path, *a, **kw)  # type: ignore[arg-type]

    monkeypatch.setattr(rr.RecordingStream, "log", counting_log)
    rec = rr.RecordingStream("dashboard_unit_test")
    rec.save(tmp_path / "x.rrd")
    b = Batcher(rec, Channels())
    batches = _stack_batches(2000)
    for batch in batches[:30]:
        b.process(batch, flush=True)
    after_first = len(calls)
    for batch in batches[30:]:
        b.process(batch, flush=True)
    rec.disconnect()
    # only once-per-entity static series names; nothing grows with the number of messages
    assert len(calls) == after_first
    assert len(set(calls)) == len(calls)


def test_garbage_is_rejected_and_counted_not_raised(tmp_path: Path) -> None:
    good = fake_stack.state(5000)
    good.header.send_mono_ns = T0
    cmd = torque_command_t()  # right size, wrong type on CASSIE_STATE
    rec = rr.RecordingStream("dashboard_unit_test")
    rec.save(tmp_path / "x.rrd")
    b = Batcher(rec, Channels())
    b.process({"CASSIE_STATE": [b"\x00" * 3, cmd.encode(), good.encode(), b"junk" * 40]})
    rec.disconnect()
    assert b.rejected == {"CASSIE_STATE": 3}
    assert not b.errors
    assert b.sim_us == 5000


def test_read_headers_agrees_with_the_full_decoder() -> None:
    msgs = []
    for k in range(5):
        m = fake_stack.state(1000 * k + 7)
        m.header.seq, m.header.send_mono_ns, m.header.source = k, T0 + k, "x" * k
        msgs.append(m.encode())
    h = read_headers(msgs, fingerprint(robot_state_t))
    for i, raw in enumerate(msgs):
        d = robot_state_t.decode(raw).header
        assert (h.utime[i], h.seq[i], h.mono_ns[i]) == (d.utime, d.seq, d.send_mono_ns)


def test_reduce_max_bounds_rows_and_keeps_the_spike() -> None:
    vals = np.full(1000, 0.2)
    vals[617] = 9.0
    vals[100] = np.nan
    k = np.arange(1000, dtype=np.int64)
    wall = T0 + k * 500_000  # 2 kHz for 0.5 s
    sim, w, out = reduce_max(k, wall, vals, 10_000_000)  # 100 points per second
    assert 50 <= len(out) <= 51
    assert out.max() == 9.0 and 617 in sim and wall[617] in w
    assert np.all(np.diff(sim) > 0)  # order kept
    rows = np.column_stack([vals, vals * 2])
    _, _, out2 = reduce_max(k, wall, rows, 10_000_000)
    assert out2.shape == (len(out), 2) and out2[:, 1].max() == 18.0
    sparse = reduce_max(k[:5], wall[:5] * 100, vals[:5], 10_000_000)  # 50 ms apart: all kept
    assert len(sparse[2]) == 5


def test_pick_by_period_spaces_rows_in_sim_time() -> None:
    utime = np.arange(0, 200_000, 500, dtype=np.int64)  # 2 kHz for 0.2 s
    picks, last = pick_by_period(utime, 33_333, -(1 << 62), cap=100)
    assert len(picks) == 6 and last == utime[picks[-1]]
    picks2, _ = pick_by_period(np.array([1000, 1500]), 33_333, last, cap=4)  # sim restarted
    assert picks2 == [0]


def test_polygon_mask_either_winding() -> None:
    square = np.array([[0.0, 0.0, 0], [1.0, 0, 0], [1.0, 1.0, 0], [0.0, 1.0, 0]])
    for poly in (square, square[::-1]):
        m = polygon_mask([poly], np.array([-0.5, -0.5]), 0.25, (9, 9))
        assert m.sum() == 25  # centres 0, 0.25, ..., 1.0 in x and y
        assert m[2, 2] and m[6, 6] and not m[1, 2] and not m[2, 7]


def test_terrain_boxes_are_logged_once_as_static(tmp_path: Path) -> None:
    pytest.importorskip("sim.terrain")
    from tools.dashboard.terrain import find_terrain, log_terrain

    terrain = find_terrain(None, "stairs")
    assert terrain is not None and len(terrain.boxes) > 1
    rec = rr.RecordingStream("dashboard_unit_test")
    rec.save(tmp_path / "t.rrd")
    assert log_terrain(rec, terrain) == len(terrain.boxes)
    rec.disconnect()
    out = read_rrd(tmp_path / "t.rrd")
    assert out.timelines["/world/terrain"] == set()  # static
    assert len(out.column("/world/terrain", "Boxes3D:centers")[0]) == len(terrain.boxes)


def test_channel_names_follow_the_profile(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from tools.dashboard.channels import resolve_setup

    prof = tmp_path / "renamed.yaml"
    prof.write_text(
        "profile: renamed\n"
        "hosts: {nuc: {address: 127.0.0.1}}\n"
        "channels: {state: MY_STATE, tick: TEST_TICK}\n"
        "supervisor: {timing_channel: MY_TIMING}\n"
        "processes:\n"
        "  ticker: {host: nuc, module: tests.procs.ticker, rate_hz: 10, outputs: {out: tick}}\n"
        "launch: [ticker]\n"
    )
    monkeypatch.setenv("CASSIE_LCM_URL", "udpm://239.255.76.67:23456")
    setup = resolve_setup(str(prof))
    assert setup.lcm_url == "udpm://239.255.76.67:23456"
    assert setup.channels.state == "MY_STATE" and setup.channels.timing == "MY_TIMING"
    assert setup.channels.torque == "OSC_TORQUE"  # not in the profile: the default
    caps = setup.channels.capacities()
    assert caps["MY_STATE"] == 8192 and caps["DEPTH"] == 256
    assert setup.channels.keep_bytes() == {"DEPTH": 1024}


def test_wall_time_is_the_send_time_unless_the_clock_is_foreign(tmp_path: Path) -> None:
    local, foreign = fake_stack.state(1_000_000), fake_stack.state(2_000_000)
    local.header.send_mono_ns = time.monotonic_ns() - 30_000_000_000  # sent 30 s ago, here
    foreign.header.send_mono_ns = 5  # another host's monotonic clock
    before = time.time_ns()
    rec = _run(tmp_path, [{"CASSIE_STATE": [local.encode()]},
                          {"CASSIE_STATE": [foreign.encode()]}])
    wall = rec.column("/world/robot/pelvis", "wall_time")
    assert len(wall) == 2
    assert abs(wall[0] - (before - 30_000_000_000)) < 2_000_000_000
    assert abs(wall[1] - before) < 10_000_000_000  # arrival time instead


def test_own_drops_are_shown(tmp_path: Path) -> None:
    from tools.dashboard.collector import ChannelStats

    rec = rr.RecordingStream("dashboard_unit_test")
    rec.save(tmp_path / "d.rrd")
    b = Batcher(rec, Channels())
    stats = {"CASSIE_STATE": ChannelStats(received=1000, dropped=400), "DEPTH": ChannelStats(3)}
    b.process({}, stats, flush=True)
    rec.disconnect()
    out = read_rrd(tmp_path / "d.rrd")
    assert out.scalars("/dashboard/dropped_total") == [400.0]
    assert out.scalars("/dashboard/received_total") == [1003.0]
    assert out.scalars("/dashboard/dropped/CASSIE_STATE") == [400.0]
    assert "/dashboard/dropped/DEPTH" not in out.rows  # only channels that dropped any


def test_an_event_loops_rate_is_taken_over_a_second_not_one_window(tmp_path: Path) -> None:
    # a 15 Hz loop reporting every 0.1 s: 1 or 2 ticks a window, some with none
    msgs, total = [], 0
    pattern = [2, 1, 2, 0, 2, 1, 2, 1, 2, 2]  # 15 ticks a second
    for k in range(40):
        m = fake_stack.timing(100_000 * k, "s3", "s3", k)
        m.ticks = pattern[k % 10]
        total += m.ticks
        m.ticks_total, m.rate_hz = total, m.ticks / 0.1
        m.header.send_mono_ns = T0 + k * 100_000_000
        msgs.append(m.encode())
    rec = _run(tmp_path, [{"TIMING": msgs}])
    rates = rec.scalars("/timing/rate_hz/s3/s3")
    assert len(rates) == 40
    assert all(13.0 <= r <= 17.0 for r in rates[12:]), rates  # once a second is in view
    assert 0.0 not in rates[12:]
