"""Perception and S3 as processes: the real sim's depth frames become footholds in the harness."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from runtime.config import HW_CONFIG_DIR, load_profile
from runtime.harness import Harness


def _profile(tmp_path: Path, terrain: str):  # type: ignore[no-untyped-def]
    p = tmp_path / "perception.yaml"
    p.write_text(
        f"include: [{HW_CONFIG_DIR / 'experiment.yaml'}]\n"
        "launch: [sim, state_estimator, torque_bridge, perception, s3]\n"
        f"overrides: {{sim: {{params: {{terrain: '{terrain}', drive: periodic, "
        "camera_render: inline, publish_footholds: false}}}\n"
    )
    return load_profile(p)


def test_depth_frames_become_footholds_on_stair_treads(tmp_path):
    # Treads 45 cm deep: with perception the paper walks stairs of 40 cm depth or more (VIII-A);
    # the safety margin leaves too little of 27 cm treads.
    (tmp_path / "deep_stairs.yaml").write_text(
        "terrain: stairs\nfoothold_margin: 0.02\nparams: {rise: 0.15, depth: 0.45, count: 3,"
        " width: 2.0, start_length: 0.5, landing: 1.5}\n"
    )
    prof = _profile(tmp_path, str(tmp_path / "deep_stairs.yaml"))
    h = Harness.from_profile(prof)
    depth_sent: dict[int, int] = {}  # frame utime -> sim time it was published
    maps: list = []
    sets: list = []
    h.tap("DEPTH", lambda t, m: depth_sent.setdefault(m.header.utime, t))
    h.tap("ELEVATION_MAP", lambda t, m: maps.append(m))
    h.tap("FOOTHOLDS", lambda t, m: sets.append((t, m)))
    h.run_until(700_000)  # 0.7 s of sim time: about 20 camera frames
    h.close()
    assert len(depth_sent) >= 15
    assert len(sets) >= 10
    # every foothold set comes from a depth frame (same utime), exactly the modelled compute
    # delays after it (perception 5 ms + S3 10 ms of sim time)
    for t, fs in sets:
        assert t - depth_sent[fs.header.utime] == 15_000
    last_map = maps[-1]
    assert last_map.status_text == "ok", last_map.status_text
    last = sets[-1][1]
    assert last.status == 0 and last.num_footholds >= 2, last.status_text
    # treads are level: S3's planes are horizontal, at the heights of the ground and the steps
    heights = sorted(f.offset / f.normal[2] for f in last.footholds)
    for f in last.footholds:
        assert f.normal[2] > 0.98
    assert min(heights) < 0.05  # the ground before the stairs
    assert max(heights) > 0.12  # at least the first 15 cm step was seen


def test_bad_maps_give_status_and_no_crash():
    from lcmtypes import elevation_map_t
    from processes.s3.params import S3Params
    from processes.s3.process import S3Node
    from runtime.codecs import elevation_map_from_msg

    node = S3Node(S3Params())
    out: list = []
    ctx = type("C", (), {"now_utime": 1000, "publish": lambda self, r, m: out.append(m)})()
    for rows, cols, data, names in (
        (0, 0, b"", []),
        (4, 4, b"\x00" * 3, ["elevation"]),
        (2, 2, np.full(4, np.nan, "<f4").tobytes(), ["elevation"]),
    ):
        msg = elevation_map_t()
        msg.header.utime = 1000
        msg.rows, msg.cols, msg.resolution = rows, cols, 0.025
        msg.layer_names, msg.num_layers = names, len(names)
        msg.data, msg.num_bytes = data, len(data)
        inbox = type("I", (), {"trigger": lambda self, m=msg: m})()
        node.tick(ctx, inbox)
        assert isinstance(elevation_map_from_msg(msg), (str, dict))
    assert [m.num_footholds for m in out] == [0, 0, 0]
    assert all(m.status_text for m in out)
    assert out[0].status_text.startswith("bad input") and out[1].status_text.startswith("bad")
