"""The sim's push (hw_config/push.yaml) knocks a walking Cassie over; the sim's own judge
sees the fall and reports a fault, which is what makes a launch fail."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from runtime.config import HW_CONFIG_DIR, load_profile
from runtime.harness import Harness
from runtime.node import HEALTH_FAULT, HEALTH_OK


def _walk(tmp_path: Path, push: str, seconds: float) -> Any:
    """The experiment profile's stack in the harness, with ``push`` as the sim's push."""
    profile = tmp_path / "push.yaml"
    profile.write_text(
        f"include: [{HW_CONFIG_DIR / 'experiment.yaml'}]\nprofile: push_test\n"
        "launch: [sim, state_estimator, torque_bridge, osc, mpfc]\n"
        f"overrides: {{sim: {{params: {{push: {push}}}}}}}\n"
    )
    h = Harness.from_profile(load_profile(profile))
    h.run_until(round(seconds * 1e6))
    sim = next(b.node for b in h.bindings if b.node.name == "sim")
    h.close()
    return sim


def test_a_push_during_the_walk_is_a_fall_the_sim_reports(tmp_path: Path) -> None:
    sim = _walk(tmp_path, "{after_release_s: 2.0, force_n: [0.0, 400.0, 0.0], duration_s: 0.3}",
                4.0)
    assert sim.health() == HEALTH_FAULT
    assert "FELL at t=" in sim.status()
    counters = sim.counters()
    assert counters["fell"] == 1.0 and counters["pelvis_height_m"] < 0.6
    assert 2.0 < sim.fell_at < 3.5


def test_a_push_before_it_is_due_changes_nothing(tmp_path: Path) -> None:
    sim = _walk(tmp_path, "{after_release_s: 30.0, force_n: [0.0, 400.0, 0.0]}", 2.0)
    assert sim.health() == HEALTH_OK
    assert sim.status().startswith("walked ")
    assert 0.3 < sim.counters()["walked_m"] < 1.0
