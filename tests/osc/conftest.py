"""Shared fixtures for the OSC tests: the menagerie Cassie model and the IK standing pose."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from processes.osc.model import load_cassie, standing_pose


@pytest.fixture(scope="session")
def sim_model() -> mujoco.MjModel:
    """The simulator's model (floor, contacts), with impratio 10 as the sim uses it."""
    m = load_cassie()
    m.opt.impratio = 10.0
    return m


@pytest.fixture(scope="session")
def q_stand(sim_model: mujoco.MjModel) -> np.ndarray:
    """IK standing pose: pelvis 0.95 m, feet flat, rods closed, springs unloaded."""
    return standing_pose(sim_model)
