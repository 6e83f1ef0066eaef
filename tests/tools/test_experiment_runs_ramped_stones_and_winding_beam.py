"""`cassie experiment ramped_stones|winding_beam`: the trial's terrain file carries its seed,
d_min and width and loads; the course has an end and, winding, a centre line the operator
steers along; the command line and sweeps take the new names."""

from __future__ import annotations

import math

import numpy as np
import pytest

from lcmtypes import ground_truth_t
from runtime.config import HW_CONFIG_DIR
from sim import terrain as terrain_mod
from tools.experiment.courses import _prepare, _terrain_file, course_end_x
from tools.experiment.operator import YAW_RATE_MAX, Operator, follow


def test_the_trials_terrain_file_carries_its_seed_dmin_and_width_and_loads(tmp_path) -> None:
    ramped = terrain_mod.load_terrain(_terrain_file("ramped_stones", 0.5, 3, tmp_path))
    assert ramped.name == "ramped_stones" and ramped.seed == 3
    assert ramped.params["d_min"] == 0.5 and ramped.params["max_tilt_deg"] == 10.0
    assert ramped.params["foot_half_size"] == (0.10, 0.02)  # shrunk for the foot, as stones
    stones = terrain_mod.load_terrain(_terrain_file("stones", 0.5, 3, tmp_path))
    assert [b.size for b in stones.boxes] == [b.size for b in ramped.boxes]
    beam = terrain_mod.load_terrain(_terrain_file("winding_beam", None, 2, tmp_path, size=0.3))
    assert beam.seed == 2 and beam.params["width"] == 0.3
    assert all(b.size[1] == 0.3 for b in beam.boxes[1:-1])
    assert beam.path and course_end_x(beam) is not None
    other = terrain_mod.load_terrain(_terrain_file("winding_beam", None, 5, tmp_path))
    assert other.params["headings_deg"] != beam.params["headings_deg"]


def test_a_winding_course_gives_the_operator_its_centre_line_and_the_judge_its_end(
        tmp_path) -> None:
    *_, goal, path = _prepare(HW_CONFIG_DIR / "experiment.yaml", "winding_beam", None, 1,
                              False, tmp_path)
    ter = terrain_mod.winding_beam(seed=1)
    assert path == ter.path and goal == course_end_x(ter)
    *_, goal, path = _prepare(HW_CONFIG_DIR / "experiment.yaml", "ramped_stones", 0.5, 1,
                              False, tmp_path)
    assert path == () and goal is not None  # straight on: heading 0, as the stones


def _gt(x: float, y: float, yaw: float) -> ground_truth_t:
    m = ground_truth_t()
    m.q = [x, y, 0.95, math.cos(0.5 * yaw), 0.0, 0.0, math.sin(0.5 * yaw)] + [0.0] * 28
    return m


def test_the_operator_steers_towards_the_centre_line_ahead_and_holds_heading_0_without_one():
    path = np.array([(0.0, 0.0), (1.0, 0.0), (2.0, 1.0)])
    heading, off, normal = follow(path, 0.5, 0.0, lookahead=0.4)
    assert heading == pytest.approx(0.0) and off == 0.0 and tuple(normal) == (-0.0, 1.0)
    heading, off, _ = follow(path, 0.5, 0.2, lookahead=0.4)  # left of the line: back right
    assert off == pytest.approx(0.2) and heading == pytest.approx(math.atan2(-0.2, 0.4))
    heading, _, _ = follow(path, 0.9, 0.0, lookahead=0.4)  # the corner: into the next piece
    target = np.array((1.0, 0.0)) + 0.3 / math.sqrt(2.0)
    assert heading == pytest.approx(math.atan2(target[1], target[0] - 0.9))
    heading, _, _ = follow(path, 2.5, 1.5, lookahead=0.4)  # past the end: along the last piece
    assert heading == pytest.approx(math.pi / 4)
    winding = Operator(0.375, path=path)
    cmd = winding.command(0, _gt(0.9, 0.0, 0.0))
    assert cmd.yaw_rate > 0.3 and cmd.vx == 0.375 and cmd.vy == 0.0
    assert winding.command(0, _gt(1.5, 0.5, math.pi / 4)).yaw_rate == pytest.approx(0.0,
                                                                                  abs=1e-9)
    straight = Operator(0.375)  # no centre line: heading 0 along x, as before
    assert straight.command(0, _gt(0.9, 0.3, 0.2)).yaw_rate == pytest.approx(-0.2)
    # never beyond the radio's range, which the processes' command inputs reject whole
    assert straight.command(0, _gt(0.0, 0.0, 2.5)).yaw_rate == pytest.approx(-YAW_RATE_MAX)
    assert winding.command(0, _gt(0.9, 0.0, -2.0)).yaw_rate == pytest.approx(YAW_RATE_MAX)


def test_the_command_line_and_sweeps_take_the_new_courses(monkeypatch, tmp_path) -> None:
    import tools.experiment as ex
    import tools.experiment.sweep as sweep

    seen: dict[str, object] = {}

    class Stop(Exception):
        pass

    def fake_run_trial(name, duration, seed, dmin, *args, size=None, segmenter="s3", **kw):
        seen.update(name=name, dmin=dmin, size=size, segmenter=segmenter)
        raise Stop

    def fake_run_sweep(specs, out, jobs):
        seen["specs"] = specs
        raise Stop

    monkeypatch.setattr(ex, "run_trial", fake_run_trial)
    monkeypatch.setattr(sweep, "run_sweep", fake_run_sweep)
    with pytest.raises(Stop):
        ex.main(["ramped_stones", "--dmin", "0.5", "--perception", "--segmenter",
                 "superpixels"])
    assert seen["dmin"] == 0.5 and seen["segmenter"] == "superpixels"
    with pytest.raises(Stop):
        ex.main(["winding_beam", "--perception"])  # the perception beam's 35 cm
    assert seen["size"] == ex.PERCEPTION_BEAM_WIDTH_M
    with pytest.raises(Stop):
        ex.main(["winding_beam", "--width", "0.3"])
    assert seen["size"] == 0.3
    for wrong in (["winding_beam", "--dmin", "0.5"], ["ramped_stones", "--width", "0.3"]):
        with pytest.raises(SystemExit):
            ex.main(wrong)
    with pytest.raises(Stop):
        ex.main(["winding_beam", "--sweep", "width=0.23,0.35", "--trials", "10",
                 "--out", str(tmp_path / "s")])
    specs = seen["specs"]
    assert len(specs) == 20 and {s.size for s in specs} == {0.23, 0.35}
    assert {s.seed for s in specs} == set(range(10))
    with pytest.raises(Stop):
        ex.main(["ramped_stones", "--sweep", "dmin=0.5", "--trials", "2", "--out",
                 str(tmp_path / "r")])
    assert [s.dmin for s in seen["specs"]] == [0.5, 0.5]
