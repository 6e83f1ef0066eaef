"""The S3 process with ``method: superpixels``: an elevation map message in, the superpixels'
footholds out on the same channel, stamped with the map's time and sequence number."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from runtime.builder import build_node
from runtime.codecs import elevation_map_to_msg, footholds_from_msg
from tests.conftest import one_process


def test_a_map_of_two_levels_becomes_footholds_at_both_heights(tmp_path: Path) -> None:
    node = build_node(*one_process(tmp_path, "s3", {"method": "superpixels"},
                                   mode="lockstep"))
    cols = np.arange(100)
    e = np.where(cols[None, :] < 50, 0.0, 0.12).repeat(100, axis=0).astype(np.float32)
    msg = elevation_map_to_msg({"elevation": e}, 0.025, (1.0, -1.25), utime=2_000_000)
    msg.header.seq = 7
    out: list = []
    ctx = type("C", (), {"now_utime": 2_000_000,
                         "publish": lambda self, ch, m: out.append((ch, m))})()
    inbox = type("I", (), {"trigger": lambda self: msg})()
    node.tick(ctx, inbox)
    [(channel, fs)] = out
    assert channel == "footholds"
    assert (fs.header.utime, fs.map_seq, fs.status) == (2_000_000, 7, 0)
    heights = {round(f.height_at(f.vertices_xy.mean(axis=0)), 3) for f in footholds_from_msg(fs)}
    assert heights == {0.0, 0.12}
    assert "superpixels regions" in node.status()
