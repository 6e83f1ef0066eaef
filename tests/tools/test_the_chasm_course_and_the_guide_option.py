"""`cassie experiment chasm`: a gap of the width asked for, whose end platform is the course's
end; `--guide` adds the SLIP guide to the harness profile and turns the MPFC's guide on."""

from __future__ import annotations

from pathlib import Path

import pytest

from runtime.config import HW_CONFIG_DIR
from sim.terrain import load_terrain
from tools.experiment.courses import GUIDE_PROCESS, _prepare, course_end_x
from tools.experiment.sweep import TrialSpec


@pytest.mark.parametrize("width", [None, 0.30, 0.45])
def test_the_chasm_has_the_gap_asked_for_and_ends_at_its_far_platform(
        tmp_path: Path, width: float | None) -> None:
    _, _, _, surfaces, ground, goal, _ = _prepare(HW_CONFIG_DIR / "experiment.yaml", "chasm",
                                                  None, 0, False, tmp_path, size=width)
    gap = 0.35 if width is None else width
    assert goal == pytest.approx(1.0 + gap)
    assert ground(0.5, 0.0) == 0.0 and ground(1.0 + 0.5 * gap, 0.0) == -0.5  # the pit
    # the judge's faces: the platforms less the 2 cm margin, the gap between them
    assert sorted(round(f.vertices_xy[:, 0].min(), 3) for f in surfaces)[1] == pytest.approx(
        1.0 + gap + 0.02)


def test_a_row_of_boxes_has_an_end_and_a_heap_has_none() -> None:
    chasm = load_terrain(HW_CONFIG_DIR / "terrains" / "chasm.yaml")
    assert course_end_x(chasm) == pytest.approx(1.35)
    assert course_end_x(load_terrain(HW_CONFIG_DIR / "terrains" / "blocks.yaml")) is None


def test_guide_adds_the_guide_process_and_turns_the_mpfcs_guide_on(tmp_path: Path) -> None:
    base = HW_CONFIG_DIR / "experiment.yaml"
    _, prof, launch, *_ = _prepare(base, "chasm", None, 0, False, tmp_path, guide=True)
    assert launch[-1] == GUIDE_PROCESS and prof.processes["mpfc"].params["guide"] is True
    assert prof.processes[GUIDE_PROCESS].inputs["footholds"].name == "FOOTHOLDS"
    _, prof, launch, *_ = _prepare(base, "chasm", None, 0, False, tmp_path)
    assert GUIDE_PROCESS not in launch and prof.processes["mpfc"].params["guide"] is False


def test_a_guided_trial_is_another_trial_in_a_resumed_sweep() -> None:
    spec = TrialSpec("chasm", 12.0, 0, None, False, 0.375, "p.yaml", 0.35)
    assert spec.key() != TrialSpec(**{**spec.__dict__, "guide": True}).key()
