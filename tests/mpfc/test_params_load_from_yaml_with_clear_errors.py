"""MpfcParams from YAML (runtime.params.load): Table V values load, and bad files fail with
ConfigError naming the file and the key."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from processes.mpfc import MpfcParams
from runtime.errors import ConfigError
from runtime.params import load

YAML = Path(__file__).resolve().parents[2] / "hw_config" / "gains" / "mpfc.yaml"


def test_hardware_column_of_table_v() -> None:
    p = load(MpfcParams, YAML, "hardware")
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
    s = load(MpfcParams, YAML, "simulation")
    assert s.step_width_m == 0.15
    assert s.q_terminal == (1000.0, 1000.0, 20.0, 20.0)
    assert s.q_running == (10.0, 10.0, 5.0, 5.0)
    assert s.com_pos_limit_m == (0.4, 0.4)


def test_the_top_level_is_the_hardware_column() -> None:
    assert load(MpfcParams, YAML) == load(MpfcParams, YAML, "hardware")
    assert load(MpfcParams, YAML, "hardware") == MpfcParams()  # the defaults: hardware too


def _write(tmp_path: Path, mutate) -> Path:
    data = yaml.safe_load(YAML.read_text())
    mutate(data)  # the top level: the hardware column
    out = tmp_path / "mpfc.yaml"
    out.write_text(yaml.safe_dump(data))
    return out


@pytest.mark.parametrize(
    ("mutate", "key", "word"),
    [
        (lambda d: d.update(t_ds_s="fast"), "t_ds_s", "number"),
        (lambda d: d.update(com_height_m=-0.85), "com_height_m", "(0.0, inf] m"),
        (lambda d: d.update(q_running=[1.0, 2.0]), "q_running", "list of 4"),
        (lambda d: d.update(t_ss_min_s=0.31), "t_ss_min_s", "t_ss_min_s <= t_ss_s"),
        (lambda d: d.update(search="guess"), "search", "auto, enumerate, branch_and_bound"),
        (lambda d: d.update(r_step=[25.0, 25.0, 1.0]), "r_step", "z weight"),
        (lambda d: d.update(horizon=3), "horizon", "unknown key"),
        (lambda d: d.update(horizon_steps=2.5), "horizon_steps", "integer"),
        (lambda d: d["variants"]["simulation"].update(q_terminal=[1, 1, 1, 0]),
         "variants.simulation.q_terminal[3]", "out of range"),
    ],
)
def test_bad_values_raise_config_error_naming_file_and_key(tmp_path, mutate, key, word) -> None:
    path = _write(tmp_path, mutate)
    with pytest.raises(ConfigError) as err:
        load(MpfcParams, path, "simulation" if "simulation" in key else "hardware")
    assert err.value.key == key
    assert err.value.file == str(path)
    assert word in str(err.value)


def test_a_key_left_out_takes_the_hardware_column(tmp_path) -> None:
    path = _write(tmp_path, lambda d: d.pop("w_time"))
    assert load(MpfcParams, path, "hardware").w_time == 100.0


def test_missing_file_and_variant(tmp_path) -> None:
    with pytest.raises(ConfigError):
        load(MpfcParams, tmp_path / "nope.yaml")
    with pytest.raises(ConfigError) as err:
        load(MpfcParams, YAML, "moon")
    assert err.value.key == "variants" and err.value.allowed == "hardware, simulation"
