"""A stop for nothing ahead on one stepping stone S3 has eroded to ~20 cm stands on feet 7-8
cm apart instead of stepping in place until it falls (the paper's stones, d_min 40 cm, seed
2002, perception: before, the gait stepped in place there for 2 s and fell at 11.3 s).
Minutes of harness time: behind the ``slow`` marker."""

from __future__ import annotations

import pytest

from runtime.config import HW_CONFIG_DIR
from tools.experiment.trials import run_trial

pytestmark = pytest.mark.slow


def test_a_stop_on_one_eroded_stone_stands_on_feet_7_cm_apart():
    tr = run_trial("stones", 13.0, 2002, 0.40, True, 0.375, HW_CONFIG_DIR / "experiment.yaml")
    assert 9.0 <= tr.halt_s <= 9.6  # the stop on the stone
    assert tr.halted_at_end and not tr.fell
