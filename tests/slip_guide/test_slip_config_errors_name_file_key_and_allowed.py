"""The SLIP guide's gains file as written loads; an unknown key or a bad value stops the load
with a ConfigError naming the file, the key and what is allowed."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
import yaml

from processes.slip_guide.params import SlipParams
from runtime.config import HW_CONFIG_DIR
from runtime.errors import ConfigError
from runtime.params import load
from tests.conftest import assert_names

DEFAULT_CONFIG = HW_CONFIG_DIR / "gains" / "slip_guide.yaml"


def test_the_gains_file_as_written_loads_the_papers_table_i_settings() -> None:
    p = load(SlipParams, DEFAULT_CONFIG)
    assert (p.dt_s, p.horizon_s, p.steps, p.knn_k, p.rw_iterations) == (0.15, 1.5, 10, 20, 4)
    assert p.card_bound == 2.9 and p.path_tol_m == 0.1


@pytest.mark.parametrize(("change", "key", "problem", "allowed"), [
    ({"knn": 20}, "knn", "unknown key", None),
    ({"knn_k": 0}, "knn_k", "out of range: 0", "[1, 200]"),
    ({"friction_mu": -0.6}, "friction_mu", "out of range: -0.6", "(0.0, 5.0]"),
    ({"dt_s": "fast"}, "dt_s", "must be a number", "[0.01, 1.0] s"),
    ({"horizon_s": 0.2}, "horizon_s", "fewer than two samples", ">= 0.3 s"),
    ({"reach_m": 0.5}, "reach_m", "barely reaches the ground", "> 0.765 m"),
])
def test_a_bad_gain_names_the_file_the_key_and_what_is_allowed(
        tmp_path: Path, change: dict[str, Any], key: str, problem: str,
        allowed: str | None) -> None:
    data = yaml.safe_load(Path(DEFAULT_CONFIG).read_text())
    data.update(change)
    path = tmp_path / "slip_guide.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(ConfigError) as err:
        load(SlipParams, path)
    assert_names(err.value, path, key, problem, allowed, listing="knn_k")
