"""The start-up pose solved by IK is clean (rods closed, feet flat) where the `home` keyframe
is not, the holder keeps the robot up until released, and make_node picks the loop kind
from the profile's mode."""

from __future__ import annotations

import numpy as np

from sim.model import build_model, pose_report, standing_pose
from sim.target_pc import make_core
from sim.terrain import flat, stairs


def test_ik_standing_pose_closes_the_rods_with_feet_flat() -> None:
    m = build_model(flat())
    home = pose_report(m, m.key_qpos[0])
    ik = pose_report(m, standing_pose(m))
    assert home["closure_max_m"] > 1e-3  # the keyframe's known 1.5 mm
    assert ik["closure_max_m"] < 1e-6
    assert abs(ik["pelvis_z_m"] - 0.95) < 1e-12
    assert abs(ik["foot_z_min_m"]) < 1e-6 and abs(ik["foot_z_max_m"]) < 1e-6
    assert abs(ik["com_minus_feet_x_m"]) < 1e-4
    assert m.opt.impratio == 10.0 and m.opt.timestep == 0.0005


def test_holder_keeps_the_pelvis_up_until_released() -> None:
    core = make_core(stairs())
    z0 = core.d.qpos[2]
    core.step(400)  # 0.2 s, zero torque, held
    assert core.holder_engaged and abs(core.d.qpos[2] - z0) < 0.01
    core.command(np.zeros(10))  # zeros: the controller has not taken over yet
    assert core.holder_engaged
    core.command(np.full(10, 0.1))
    assert not core.holder_engaged
    core.command(np.zeros(10))
    core.step(400)  # no torque, no holder: the robot sags
    assert core.d.qpos[2] < z0 - 0.05


def test_make_node_is_periodic_in_realtime_and_command_driven_in_lockstep(driver_factory) -> None:
    rt = driver_factory("realtime", {"terrain": "terrains/flat.yaml"}).node
    assert rt.trigger_role is None and rt.period_s == 0.0005
    ls = driver_factory("lockstep", {"terrain": "stones", "terrain_seed": 2}).node
    assert ls.trigger_role == "command" and ls.trigger_timeout_s == 0.01
    assert ls.settings.terrain.seed == 2
    assert set(rt.outputs) == {"robot_output", "ground_truth", "depth"}
    assert rt.inputs == {"command": bytes}


def test_camera_render_off_means_no_depth_camera_and_a_bad_value_lists_it():
    """Profiles without perception switch the depth camera off (its renderer costs ~15 % of
    a core); YAML's bare ``off`` (read as false) means the same."""
    import pytest

    from runtime.builder import build_node
    from runtime.errors import ConfigError

    from .conftest import make_proc, make_profile

    for value in ("off", False):
        node = build_node(make_proc({"terrain": "flat", "camera_render": value}),
                         make_profile("lockstep"))
        try:
            assert node.render_mode == "off"
            assert "depth" not in node.status()
        finally:
            node.close()
    with pytest.raises(ConfigError, match=r"camera_render.*off"):
        build_node(make_proc({"terrain": "flat", "camera_render": "never"}),
                  make_profile("lockstep"))
