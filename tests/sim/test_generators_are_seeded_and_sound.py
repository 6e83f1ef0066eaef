"""The other terrain generators: seeded (same seed, same terrain), with the paper's stair and
beam dimensions, and random blocks that never overlap (so their top faces are true footholds)."""

from __future__ import annotations

import itertools
import math

from hypothesis import given, settings
from hypothesis import strategies as st

from sim import terrain


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_blocks_never_overlap_and_are_seeded(seed: int) -> None:
    t = terrain.blocks(seed=seed)
    assert t.boxes == terrain.blocks(seed=seed).boxes
    assert len(t.footholds) == len(t.boxes) + 1
    for a, b in itertools.combinations(t.boxes, 2):
        ra = 0.5 * math.hypot(*a.size[:2])
        rb = 0.5 * math.hypot(*b.size[:2])
        assert math.dist(a.center[:2], b.center[:2]) >= ra + rb


def test_stairs_and_beam_have_the_papers_dimensions() -> None:
    s = terrain.stairs(rise=0.15, depth=0.27, count=4)
    tops = [b.top_z for b in s.boxes]
    assert [round(z, 9) for z in tops] == [0.15, 0.30, 0.45, 0.60]
    assert all(abs(b.size[0] - 0.27) < 1e-12 for b in s.boxes[:-1])
    assert all(f.contains_xy(b.center[0], 0.0) for f, b in zip(s.footholds[1:], s.boxes,
                                                               strict=True))
    beam = terrain.beam(width=0.23, length=8.0)
    assert beam.boxes[1].size[:2] == (8.0, 0.23) and beam.ground_z == -0.5
    tread = beam.footholds[1]
    assert tread.contains_xy(4.0, 0.09) and not tread.contains_xy(4.0, 0.10)  # 2 cm margin
