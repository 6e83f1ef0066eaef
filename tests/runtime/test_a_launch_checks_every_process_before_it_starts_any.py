"""Issue 14, fault 9: a typo or NaN in a gains file, or two processes on one channel, stop a
launch before anything starts, with the file and key on the terminal (they used to surface
after a partial start, in one process's log, blamed on the wrong process)."""

from __future__ import annotations

from pathlib import Path

from runtime.config import HW_CONFIG_DIR
from tests.conftest import cassie

OSC_GAINS = HW_CONFIG_DIR / "gains" / "osc.yaml"


def _run(*args: str) -> tuple[int, str]:
    p = cassie(*args)
    out, _ = p.communicate(timeout=240)  # (stderr goes to stdout)
    return p.returncode, out


def test_a_nan_in_the_osc_gains_stops_the_launch_before_any_process_starts(lcm_url,
                                                                           tmp_path: Path):
    gains = tmp_path / "osc.yaml"
    text = OSC_GAINS.read_text()
    assert "  fall_height: 0.6 " in text
    gains.write_text(text.replace("  fall_height: 0.6 ", "  fall_height: .nan "))
    profile = tmp_path / "bad_gains.yaml"
    profile.write_text(f"include: [{HW_CONFIG_DIR / 'sim.yaml'}]\nprofile: bad_gains\n"
                       "launch: [sim, state_estimator, torque_bridge, osc, mpfc]\n"
                       f"overrides: {{osc: {{gains: '{gains}'}}}}\n")
    logs = tmp_path / "logs"
    code, out = _run("launch", str(profile), "--no-live", "--duration", "5",
                     "--log-dir", str(logs))
    assert code == 2, out
    assert str(gains) in out and "safety.fall_height" in out, out
    assert "nothing was started" in out
    assert not logs.exists() or not list(logs.glob("*.log")), "a process was started"


def test_two_processes_publishing_one_channel_are_refused_by_cassie_check(tmp_path: Path):
    profile = tmp_path / "two_footholds.yaml"
    profile.write_text(f"include: [{HW_CONFIG_DIR / 'sim_perception.yaml'}]\n"
                       "profile: two_footholds\n"
                       "launch: [sim, state_estimator, torque_bridge, osc, mpfc, perception, s3]\n"
                       "overrides: {sim: {params: {publish_footholds: true}}}\n")
    code, out = _run("check", str(profile))
    assert code == 2, out
    assert "processes.s3.outputs.footholds: channel FOOTHOLDS is already published by sim" in out


def test_the_product_profiles_check_clean():
    for name in ("sim.yaml", "sim_perception.yaml", "experiment.yaml"):
        code, out = _run("check", str(HW_CONFIG_DIR / name))
        assert code == 0, out
        assert "all good" in out
