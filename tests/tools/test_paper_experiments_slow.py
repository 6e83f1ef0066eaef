"""The paper's simulation experiments as they are recorded in docs/reports/paper.md, in small:
a few terrains of Fig. 12 and the two courses of Fig. 11, with ground-truth state and terrain
(``pytest -m slow``; the full sweeps are the commands in paper.md)."""

from __future__ import annotations

import pytest

from runtime.config import HW_CONFIG_DIR
from tools.experiment.trials import run_trial

pytestmark = pytest.mark.slow
PROFILE = HW_CONFIG_DIR / "experiment.yaml"


@pytest.mark.parametrize("dmin", [0.5, 0.6])
def test_stepping_stones_from_50_cm_are_crossed_with_ground_truth(dmin):
    trials = [run_trial("stones", 20.0, seed, dmin, False, 0.375, PROFILE, true_state=True)
              for seed in range(2000, 2004)]
    assert sum(t.success for t in trials) >= 3, [(t.seed, t.fell, t.footsteps_outside)
                                                 for t in trials]
    assert not any(t.fell and t.halted_at_end for t in trials)


def test_the_23_cm_beam_and_the_27_cm_stairs_are_crossed_with_ground_truth():
    beam = run_trial("beam", 30.0, 0, None, False, 0.375, PROFILE, true_state=True)
    stairs = run_trial("stairs", 15.0, 0, None, False, 0.375, PROFILE, true_state=True)
    assert beam.crossed and not beam.fell, beam
    assert stairs.crossed and not stairs.fell, stairs


def test_the_35_cm_beam_is_crossed_with_perception_after_the_starts_stop():
    """With perception the gait stops at the start (no footholds before the first map) and
    walks on from standing: the start's weight shift with the leading foot kept loaded
    (``GaitClock.from_standing``, ``WalkingController._double_stance``). Before, it walked
    on with a 24 cm capture step, or the new stance foot slid 7 cm, and fell off the beam."""
    beam = run_trial("beam", 30.0, 0, None, True, 0.375, PROFILE, size=0.35)
    assert beam.halts >= 1 and beam.crossed and not beam.fell, beam
