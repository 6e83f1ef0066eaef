"""The gains file: Table VII values load; a bad value names the file and the key."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from processes.osc.tasks import DEFAULT_GAINS_FILE, OscGains, OscParams
from runtime.errors import ConfigError
from runtime.params import load


def test_default_gains_file_holds_table_vii_values():
    p = OscParams.from_gains(load(OscGains, DEFAULT_GAINS_FILE))
    w = p.walking
    np.testing.assert_allclose(w.swing_foot.kp, [400, 400, 400])
    np.testing.assert_allclose(w.swing_foot.kd, [35, 35, 25])  # x, y: not Table VII (20)
    np.testing.assert_allclose(w.pelvis.w, [2, 4, 0.02])
    np.testing.assert_allclose(w.com.kp, [0, 0, 80])
    assert w.toe.kp[0] == 1500 and w.hip_yaw.kp[0] == 100
    assert w.ankle_torque_weight == 10
    assert w.com_clip == 0.025 and w.com_filter_hz == 100 and w.swing_clearance == 0.15


def _write(tmp_path: Path, mutate) -> Path:
    raw = yaml.safe_load(DEFAULT_GAINS_FILE.read_text())
    mutate(raw)
    f = tmp_path / "osc.yaml"
    f.write_text(yaml.safe_dump(raw))
    return f


@pytest.mark.parametrize(
    "mutate, key",
    [
        (lambda r: r["walking"]["swing_foot"].__setitem__("kp", [400, 400]),
         "walking.swing_foot.kp"),
        (lambda r: r["walking"]["pelvis"].__setitem__("kd", [1, -1, 1]), "walking.pelvis.kd[1]"),
        (lambda r: r["qp"].__setitem__("mu", "high"), "qp.mu"),
        (lambda r: r["qp"].__setitem__("bogus", 1.0), "qp.bogus"),
        (lambda r: r["safety"].__setitem__("fall_height", 3.0), "safety.fall_height"),
        (lambda r: r.pop("standing"), "standing"),
        (lambda r: r["walking"].__setitem__("com_heigth", 0.8), "walking.com_heigth"),
        (lambda r: r["safety"].__setitem__("plan_fallback_s", 0.5), "safety.plan_fallback_s"),
    ],
)
def test_bad_gain_value_raises_config_error_naming_the_key(tmp_path, mutate, key):
    f = _write(tmp_path, mutate)
    with pytest.raises(ConfigError) as e:
        load(OscGains, f)
    assert e.value.key == key
    assert str(f) in str(e.value)
