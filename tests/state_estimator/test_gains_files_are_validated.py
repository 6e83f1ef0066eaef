"""The estimator's and the bridge's gains files load, and bad values name file and key."""

from __future__ import annotations

from pathlib import Path

import pytest

from processes.state_estimator.params import DEFAULT_GAINS_FILE, EstimatorParams
from processes.torque_bridge.bridge import DEFAULT_GAINS_FILE as BRIDGE_GAINS
from processes.torque_bridge.bridge import BridgeGains, BridgeParams
from runtime.errors import ConfigError
from runtime.params import load


def test_shipped_gains_files_load():
    p = load(EstimatorParams, DEFAULT_GAINS_FILE)
    assert p.network_every == 10 and p.contact.off_n < p.contact.on_n
    b = BridgeParams.from_gains(load(BridgeGains, BRIDGE_GAINS))
    assert b.fallback in ("zero", "damping") and len(b.torque_limit) == 10


@pytest.mark.parametrize(
    ("doc", "key"),
    [
        ({"inekf": {"gyro": -1.0}}, "inekf.gyro"),
        ({"inekf": {"gyros": 1.0}}, "inekf.gyros"),
        ({"contact": {"on_n": 10.0, "off_n": 20.0}}, "contact.off_n"),
        ({"contact": {"touchdown_speed_mps": 0.0}}, "contact.touchdown_speed_mps"),
        ({"alip": {"height": "tall"}}, "alip.height"),
        ({"network_every": 0}, "network_every"),
        ({"init": {"xy_m": [1.0]}}, "init.xy_m"),
        ({"bogus": 1}, "bogus"),
    ],
)
def test_bad_estimator_values_raise_config_error_naming_the_key(tmp_path: Path, doc, key):
    import yaml

    f = tmp_path / "se.yaml"
    f.write_text(yaml.safe_dump(doc))
    with pytest.raises(ConfigError) as exc:
        load(EstimatorParams, f)
    assert exc.value.key == key and str(f) in str(exc.value)


@pytest.mark.parametrize(
    ("doc", "key"),
    [
        ({"watchdog_ms": 0}, "watchdog_ms"),
        ({"fallback": "brake"}, "fallback"),
        ({"torque_limit_nm": {"hip_roll": 1.0}}, "torque_limit_nm.hip_yaw"),
        ({"torque_limit_nm": {"hip_roll": 0, "hip_yaw": 1, "hip_pitch": 1, "knee": 1,
                              "foot": 1}}, "torque_limit_nm.hip_roll"),
        ({"damping_kd": {"hip_roll": -1, "hip_yaw": 1, "hip_pitch": 1, "knee": 1,
                         "foot": 1}}, "damping_kd.hip_roll"),
        ({"release_holder": "yes"}, "release_holder"),
    ],
)
def test_bad_bridge_values_raise_config_error_naming_the_key(tmp_path: Path, doc, key):
    import yaml

    f = tmp_path / "tb.yaml"
    f.write_text(yaml.safe_dump(doc))
    with pytest.raises(ConfigError) as exc:
        load(BridgeGains, f)
    assert exc.value.key == key
