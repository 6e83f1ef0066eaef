"""The MPFC node leaves out footholds no leg reaches in height (a pit's floor, off a landing)."""

from __future__ import annotations

import numpy as np
import pytest

from processes.mpfc.gait import within_height
from runtime.errors import ConfigError
from runtime.geometry import Foothold
from tests.mpfc.test_mpfc_process_gait import _proc


def _square(x0: float, z: float, slope: float = 0.0) -> Foothold:
    v = np.array([[x0, -0.2], [x0 + 0.4, -0.2], [x0 + 0.4, 0.2], [x0, 0.2]])
    n = np.array([-slope, 0.0, 1.0])  # z = z0 + slope * x
    return Foothold.from_polygon(v, n, z)


def test_footholds_beyond_the_height_limit_are_left_out_and_the_rest_kept_as_objects() -> None:
    ground, tread, pit, landing = _square(0.0, 0.0), _square(0.4, 0.3), _square(0.8, -0.5), \
        _square(1.2, 0.9)
    kept = within_height([ground, tread, pit, landing], 0.0, 0.35)
    assert kept == [ground, tread]
    assert kept[0] is ground                        # the solver caches by identity
    assert within_height([ground, pit], 0.0, 0.0) == [ground, pit]   # 0: no limit


def test_a_sloped_foothold_counts_by_its_nearest_corner() -> None:
    ramp = _square(0.0, 0.0, slope=1.0)             # z from 0.0 to 0.4 over its corners
    assert within_height([ramp], 0.7, 0.35) == [ramp]
    assert within_height([ramp], 0.8, 0.35) == []


def test_a_foot_steps_at_most_the_limit_above_the_lower_foot_or_below_the_higher_one() -> None:
    ground, t1, t2, t3 = (_square(0.0, 0.0), _square(0.4, 0.15), _square(0.8, 0.3),
                          _square(1.2, 0.45))
    # stance on tread 2, the swing foot lifted off tread 1: tread 3 is 30 cm above it
    assert within_height([ground, t1, t2, t3], 0.3, 0.2, z_other=0.15) == [t1, t2]
    # both feet on tread 2: tread 3 is one rise up
    assert within_height([ground, t1, t2, t3], 0.3, 0.2, z_other=0.3) == [t1, t2, t3]


def test_a_bad_height_limit_is_a_clear_config_error() -> None:
    from runtime.builder import build_node

    with pytest.raises(ConfigError, match=r"processes\.mpfc\.params\.foothold_max_height_m: "
                                          r"out of range: -1\.0 \(allowed: \[0\.0, inf\] m\)"):
        build_node(_proc(foothold_max_height_m=-1.0), None)  # type: ignore[arg-type]
