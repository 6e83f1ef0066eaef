"""The DCM planner in the footstep planner's place (``params.planner: dcm``): the same OSC,
estimator and sim walk Cassie on it in the deterministic harness; a bad planner name is a
config error that names the key and the choices."""

from __future__ import annotations

import pytest

from runtime.config import HW_CONFIG_DIR, ConfigError
from tools.experiment.courses import planner_params
from tools.experiment.trials import run_trial


def test_cassie_walks_on_flat_ground_with_the_dcm_planner_from_standing():
    tr = run_trial("flat", 6.0, 0, None, False, 0.375, HW_CONFIG_DIR / "experiment.yaml",
                   planner="dcm")
    assert not tr.fell
    assert tr.footsteps >= 10
    assert 1.2 < tr.distance_m < 3.5  # 0.375 m/s for ~5 s after the start's weight shift
    assert tr.footsteps_outside == 0


def test_the_planner_is_chosen_by_name_and_a_bad_one_is_refused():
    assert planner_params("mpfc") == {"planner": "mpfc"}
    assert planner_params("dcm") == {"planner": "dcm", "dcm_variant": "A"}
    assert planner_params("dcm-C") == {"planner": "dcm", "dcm_variant": "C"}
    with pytest.raises(ValueError, match="one of mpfc, dcm"):
        planner_params("astar")


def test_an_unknown_planner_in_the_process_params_names_the_key_and_the_choices(tmp_path):
    import importlib

    from runtime.builder import read_config
    from runtime.config import load_profile

    prof = tmp_path / "p.yaml"
    prof.write_text(f"include: [{HW_CONFIG_DIR / 'sim.yaml'}]\nprofile: bad_planner\n"
                    "launch: [sim, state_estimator, torque_bridge, osc, mpfc]\n"
                    "overrides: {mpfc: {params: {planner: astar}}}\n")
    profile = load_profile(prof)
    proc = profile.processes["mpfc"]
    with pytest.raises(ConfigError) as err:
        read_config(proc, importlib.import_module(proc.module))
    assert "planner" in str(err.value) and "dcm" in str(err.value)
