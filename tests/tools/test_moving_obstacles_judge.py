"""Table IV's judge (``tools.experiment.obstacles``): a cube's footprint on S3's safe mask,
and a short run in which a cube dropped in front of the standing robot is segmented out."""

from __future__ import annotations

import numpy as np
import pytest

from tools.experiment.obstacles import footprint_unsafe, run_cubes_trial


def test_the_footprint_reads_the_cells_under_the_cube_only():
    mask = np.ones((40, 40), np.uint8)
    origin = np.array([0.0, 0.0])
    assert footprint_unsafe(mask, origin, 0.025, 0.5, 0.5, 0.065) == (False, True)
    mask[20, 20] = 0  # the cell at (0.5, 0.5)
    assert footprint_unsafe(mask, origin, 0.025, 0.5, 0.5, 0.065) == (True, True)
    assert footprint_unsafe(mask, origin, 0.025, 0.7, 0.5, 0.065) == (False, True)
    # a cube off the map is not judged
    assert footprint_unsafe(mask, origin, 0.025, 0.99, 0.5, 0.065)[1] is False


@pytest.mark.slow
def test_a_cube_dropped_before_the_standing_robot_is_segmented_out_without_hysteresis():
    tr = run_cubes_trial(0.0, True, cubes=1, first_s=2.0)
    assert not tr.fell
    (cube,) = tr.cubes
    assert cube.seen and cube.segmented and cube.dropped_s <= cube.hole_s <= cube.rest_s
