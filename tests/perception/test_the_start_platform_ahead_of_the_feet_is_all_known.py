"""At the start the elevation map knows all of the platform ahead of the feet: the initial
submap under the feet reaches the camera's nearest ground. A band left unknown between them is
filled by LNV inpainting with the lowest value on its rim, a pit floor it connects to round the
platform's unseen sides: a trench across the start platform (a beam's junction cut off, a
stepping-stone start stepped in place; measured before the submap's front went from 0.2 to
0.28 m)."""

from __future__ import annotations

import numpy as np

from runtime.codecs import elevation_map_from_msg
from runtime.config import HW_CONFIG_DIR
from tools.experiment.trials import run_trial


def test_the_start_platform_ahead_of_the_feet_is_all_known_after_the_first_frames() -> None:
    maps: list = []

    def setup(h) -> None:
        h.tap("ELEVATION_MAP", lambda t, m: maps.append(m))

    run_trial("beam", 0.3, 0, None, True, 0.375, HW_CONFIG_DIR / "experiment.yaml",
              setup=setup, size=0.35)
    assert maps
    m = maps[-1]
    layers = elevation_map_from_msg(m)
    assert isinstance(layers, dict)
    e = layers["elevation"]
    x = m.origin[0] + np.arange(m.cols) * m.resolution
    y = m.origin[1] + np.arange(m.rows) * m.resolution
    # the start platform from the feet (x = -0.02) to 4 cm short of its edge at x = 0.3,
    # across the feet
    band = e[np.ix_((np.abs(y) <= 0.25), (x >= 0.0) & (x <= 0.26))]
    assert band.size and np.all(np.isfinite(band)), np.argwhere(~np.isfinite(band))
    np.testing.assert_allclose(band, 0.0, atol=0.03)  # the platform's top, not a pit
