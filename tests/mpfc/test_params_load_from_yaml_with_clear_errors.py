"""MpfcParams.from_yaml: Table V values load, and bad files fail with ConfigError naming the key."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from processes.mpfc import MpfcParams
from runtime.errors import ConfigError

YAML = Path(__file__).resolve().parents[2] / "hw_config" / "gains" / "mpfc.yaml"


def test_hardware_column_of_table_v() -> None:
    p = MpfcParams.from_yaml(YAML, "hardware")
    assert p.horizon_steps == 2
    assert (p.t_ss_min_s, p.t_ss_max_s, p.t_ss_s, p.t_ds_s) == (0.27, 0.33, 0.3, 0.1)
    assert p.com_height_m == 0.85 and p.step_width_m == 0.2
    assert (p.w_time, p.w_ankle, p.ankle_torque_max_nm) == (100.0, 0.01, 22.0)
    assert p.q_terminal == (100.0, 100.0, 1.0, 1.0)
    assert p.q_running == (0.001, 0.1, 0.01, 0.001)
    assert p.r_step == (25.0, 25.0, 0.0)
    assert p.com_pos_limit_m == (0.35, 0.35) and p.com_vel_limit_mps == (2.5, 1.5)
    assert p.soft_constraint_cost == 1000.0 and p.big_m_m == 10.0


def test_simulation_column_differs_where_table_v_does() -> None:
    s = MpfcParams.from_yaml(YAML, "simulation")
    assert s.step_width_m == 0.15
    assert s.q_terminal == (1000.0, 1000.0, 20.0, 20.0)
    assert s.q_running == (10.0, 10.0, 5.0, 5.0)
    assert s.com_pos_limit_m == (0.4, 0.4)


def _write(tmp_path: Path, mutate) -> Path:
    data = yaml.safe_load(YAML.read_text())
    mutate(data["hardware"])
    out = tmp_path / "mpfc.yaml"
    out.write_text(yaml.safe_dump(data))
    return out


@pytest.mark.parametrize(
    ("mutate", "key", "word"),
    [
        (lambda d: d.pop("w_time"), "hardware.w_time", "missing"),
        (lambda d: d.update(t_ds_s="fast"), "hardware.t_ds_s", "number"),
        (lambda d: d.update(com_height_m=-0.85), "hardware.com_height_m", "> 0"),
        (lambda d: d.update(q_running=[1.0, 2.0]), "hardware.q_running", "list of 4"),
        (lambda d: d.update(t_ss_min_s=0.31), "hardware.t_ss_min_s", "t_ss_min_s"),
        (lambda d: d.update(search="guess"), "hardware.search", "unknown mode"),
        (lambda d: d.update(r_step=[25.0, 25.0, 1.0]), "hardware.r_step", "z weight"),
        (lambda d: d.update(horizon=3), "hardware.horizon", "unknown parameter"),
        (lambda d: d.update(horizon_steps=2.5), "hardware.horizon_steps", "integer"),
    ],
)
def test_bad_values_raise_config_error_naming_file_and_key(tmp_path, mutate, key, word) -> None:
    path = _write(tmp_path, mutate)
    with pytest.raises(ConfigError) as err:
        MpfcParams.from_yaml(path, "hardware")
    assert err.value.key == key
    assert err.value.file == str(path)
    assert word in str(err.value)


def test_missing_file_and_variant(tmp_path) -> None:
    with pytest.raises(ConfigError):
        MpfcParams.from_yaml(tmp_path / "nope.yaml")
    with pytest.raises(ConfigError) as err:
        MpfcParams.from_yaml(YAML, "moon")
    assert err.value.key == "moon"
