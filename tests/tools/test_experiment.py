"""`cassie experiment` judges trials from ground truth: falls, distance, footholds."""

from __future__ import annotations

import numpy as np
import pytest

from lcmtypes import ground_truth_t
from runtime.config import HW_CONFIG_DIR
from runtime.geometry import Foothold
from tools.experiment import Judge, run_trial
from tools.experiment import main as experiment_main


def _gt(t: float, x: float, z: float, contact: tuple[bool, bool], feet) -> ground_truth_t:  # type: ignore[no-untyped-def]
    m = ground_truth_t()
    m.header.utime = int(t * 1e6)
    m.q = [x, 0.0, z] + [0.0] * 32
    m.foot_contact = list(contact)
    m.foot_pos = [list(f) for f in feet]
    return m


def test_judge_counts_falls_distance_and_footsteps_outside_footholds():
    square = np.array([[0, -0.5], [1, -0.5], [1, 0.5], [0, 0.5]], dtype=float)
    judge = Judge([Foothold.from_ccw(square, (0.0, 0.0, 1.0), 0.0)], walk_start_s=0.0)
    feet_in = [(0.2, 0.1, 0.0), (0.2, -0.1, 0.0)]
    judge(0, _gt(0.0, 0.0, 0.95, (True, True), feet_in))
    judge(0, _gt(0.5, 0.2, 0.95, (True, False), feet_in))  # right foot lifts
    judge(0, _gt(1.0, 0.4, 0.95, (True, True), [(0.2, 0.1, 0), (0.6, -0.1, 0)]))  # lands inside
    judge(0, _gt(1.5, 0.6, 0.95, (False, True), feet_in))
    judge(0, _gt(2.0, 0.8, 0.95, (True, True), [(1.4, 0.1, 0), (0.6, -0.1, 0)]))  # lands outside
    judge(0, _gt(2.5, 0.9, 0.55, (True, True), feet_in))  # pelvis below 0.6 m: a fall
    assert len(judge.touchdowns) == 2
    assert judge.outside() == 1
    assert judge.fall_t == 2.5
    assert np.isclose(judge.x_last - judge.x0, 0.9)


def test_experiment_without_a_controller_is_reported_as_failed_not_faked(tmp_path):
    base = tmp_path / "no_controller.yaml"
    base.write_text(f"include: [{HW_CONFIG_DIR / 'experiment.yaml'}]\n"
                    "launch: [sim, state_estimator, torque_bridge]\n")
    trial = run_trial("flat", 0.3, 0, None, False, 0.375, base)
    assert not trial.fell and trial.min_pelvis_height_m > 0.9  # held by the start-up holder
    assert abs(trial.distance_m) < 0.01
    assert not trial.success


def test_short_flat_walk_in_the_harness_keeps_up_with_the_command():
    """The whole stack (sim, estimator, bridge, OSC, MPFC) in the deterministic harness: Cassie
    leaves the holder, walks 6 s of sim time on flat ground without falling, at the commanded
    speed within 15%, with one touchdown per planned step."""
    trial = run_trial("flat", 6.0, 0, None, False, 0.375, HW_CONFIG_DIR / "experiment.yaml")
    assert not trial.fell, trial
    assert trial.min_pelvis_height_m > 0.85
    assert trial.velocity_error_ratio <= 0.15, trial.mean_velocity_mps
    # T_ss + T_ds = 0.4 s per step: about 15 steps in 6 s (the first starts after 0.1 s)
    assert 12 <= trial.footsteps <= 16, trial.footsteps
    assert trial.success


def test_judge_measures_the_pelvis_over_the_terrain_under_it():
    """On stairs a robot lying on the landing keeps its pelvis above 0.6 m: still a fall."""
    from sim.terrain import load_terrain

    ground = load_terrain(HW_CONFIG_DIR / "terrains" / "stairs.yaml").height_at
    assert ground(0.0, 0.0) == 0.0 and np.isclose(ground(0.7, 0.0), 0.15)
    assert np.isclose(ground(3.0, 0.0), 0.9)  # the landing
    judge = Judge([], walk_start_s=0.0, ground=ground)
    feet = [(3.0, 0.1, 0.9), (3.0, -0.1, 0.9)]
    judge(0, _gt(0.0, 3.0, 1.85, (True, True), feet))  # standing on the landing
    assert judge.fall_t is None
    judge(0, _gt(0.5, 3.0, 1.2, (False, False), feet))  # lying on it
    assert judge.fall_t == 0.5


def test_stairs_depth_writes_a_terrain_with_that_tread_depth(tmp_path) -> None:
    from sim import terrain as terrain_mod
    from tools.experiment import _terrain_file

    ter = terrain_mod.load_terrain(_terrain_file("stairs", None, 0, tmp_path, size=0.40))
    assert ter.params["depth"] == pytest.approx(0.40)
    tops = sorted(b.top_z for b in ter.boxes)
    assert tops[0] == pytest.approx(0.15)
    assert terrain_mod.load_terrain(_terrain_file("stairs", None, 0, tmp_path)).params[
        "depth"] == pytest.approx(0.27)
    with pytest.raises(SystemExit):
        experiment_main(["flat", "--depth", "0.4"])


def test_stairs_and_beam_with_perception_default_to_the_papers_sizes(monkeypatch, capsys):
    import tools.experiment as ex

    seen = {}

    class Stop(Exception):
        pass

    def fake_run_trial(*args, size=None, **kw):
        seen["depth"] = size
        raise Stop

    monkeypatch.setattr(ex, "run_trial", fake_run_trial)
    with pytest.raises(Stop):
        ex.main(["stairs", "--perception"])
    assert seen["depth"] == ex.PERCEPTION_STAIRS_DEPTH_M == 0.40
    assert "Fig. 11" in capsys.readouterr().out
    with pytest.raises(Stop):
        ex.main(["stairs"])  # true footholds: the terrain file's 27 cm
    assert seen["depth"] is None
    with pytest.raises(Stop):
        ex.main(["stairs", "--perception", "--depth", "0.5"])
    assert seen["depth"] == 0.5
    with pytest.raises(Stop):
        ex.main(["beam", "--perception"])  # and the beam: 35 cm
    assert seen["depth"] == ex.PERCEPTION_BEAM_WIDTH_M == 0.35
    with pytest.raises(Stop):
        ex.main(["beam", "--width", "0.3"])
    assert seen["depth"] == 0.3


def test_fixed_timing_pins_the_stance_time_to_its_nominal_in_the_variant_that_runs(
        tmp_path) -> None:
    """The paper's Fixed-T: t_min = t_max = T_ss in the MPFC's gains, whichever of its Table V
    columns the profile runs; Opt-T (the default) leaves them as written."""
    import importlib

    from runtime.config import HW_CONFIG_DIR
    from runtime.params import load
    from tools.experiment.courses import _prepare

    for fixed in (False, True):
        work = tmp_path / str(fixed)
        work.mkdir()
        _, profile, *_ = _prepare(HW_CONFIG_DIR / "experiment.yaml", "flat", None, 0, False,
                                  work, fixed_timing=fixed)
        mpfc = profile.processes["mpfc"]
        gains = load(importlib.import_module(mpfc.module).Gains, mpfc.gains_file,
                     mpfc.params.get("variant", "simulation"))
        if fixed:
            assert gains.t_ss_min_s == gains.t_ss_max_s == gains.t_ss_s == 0.30
        else:
            assert (gains.t_ss_min_s, gains.t_ss_max_s) == (0.27, 0.33)


def test_a_fall_counts_as_stopped_only_when_the_stop_came_a_step_before_it():
    from tools.experiment.judge import Trial

    base = dict(experiment="stones", seed=0, fell=True, fall_time_s=6.0, halted_at_end=True)
    assert Trial(**base, halt_s=4.0).fell_while_stopped  # stopped, then fell
    assert not Trial(**base, halt_s=5.9).fell_while_stopped  # the fall made it stop
    assert not Trial(**base, halt_s=-1.0).fell_while_stopped  # walking on when it fell
    assert not Trial(**{**base, "fell": False}, halt_s=4.0).fell_while_stopped
    # a stop begun with the stance foot off the course: the fall (a foot off the beam) began it
    assert not Trial(**base, halt_s=4.0, halt_on_foothold=False).fell_while_stopped
    # ... or with the CoM already thrown (1.3 m/s) by the step before: not the stop's fall
    assert Trial(**base, halt_s=4.0, halt_speed_mps=0.8).fell_while_stopped
    assert not Trial(**base, halt_s=4.0, halt_speed_mps=1.3).fell_while_stopped
    # ... or with a foot already on a stone's edge (off its true face): falling already
    assert not Trial(**base, halt_s=4.0, halt_feet_on_footholds=False).fell_while_stopped


def test_the_judge_reads_the_coms_speed_at_a_given_time():
    """``Judge.speed_at``: the horizontal CoM speed of the first ground-truth message at or
    after the time (a stop's start), from the messages it has watched."""
    from types import SimpleNamespace

    from tools.experiment.judge import Judge

    j = Judge([], walk_start_s=0.0)
    assert j.speed_at(1.0) == 0.0
    for k, v in enumerate((0.2, 0.5, 1.2)):
        gt = SimpleNamespace(header=SimpleNamespace(utime=int(k * 1e6)), q=[0.0, 0.0, 1.0],
                             com_vel=[v * 0.6, v * 0.8, -1.0], foot_contact=[True, True],
                             foot_pos=[[0, 0, 0], [0, 0, 0]])
        j(int(k * 1e6), gt)
    assert abs(j.speed_at(0.5) - 0.5) < 1e-12 and abs(j.speed_at(2.0) - 1.2) < 1e-12
    assert abs(j.speed_at(9.0) - 1.2) < 1e-12


def test_the_judge_tells_whether_both_feet_were_on_footholds_at_a_given_time():
    """``Judge.feet_on_footholds_at``: the sim's two foot positions in the first message at or
    after the time (a stop's start), each on a true foothold or not."""
    from types import SimpleNamespace

    from tools.experiment.judge import Judge

    stone = Foothold.from_polygon(np.array([[0.0, 0.0], [0.4, 0.0], [0.4, 0.4], [0.0, 0.4]]))
    j = Judge([stone], walk_start_s=0.0)
    # both on the stone, then the right foot 3 cm past its edge, then back on
    for k, yr in enumerate((0.1, 0.43, 0.2)):
        gt = SimpleNamespace(header=SimpleNamespace(utime=int(k * 1e6)), q=[0.2, 0.2, 1.0],
                             com_vel=[0.0, 0.0, 0.0], foot_contact=[True, True],
                             foot_pos=[[0.2, 0.3, 0.0], [0.2, yr, 0.0]])
        j(int(k * 1e6), gt)
    assert j.feet_on_footholds_at(0.0) and j.feet_on_footholds_at(2.0)
    assert not j.feet_on_footholds_at(0.5) and not j.feet_on_footholds_at(1.0)


def test_a_robot_that_stops_at_the_start_for_want_of_footholds_stands_and_the_trial_ends():
    """Treads of 21 cm leave no foothold for the 20 cm blade: the MPFC stops before the first
    step and Cassie stands; 5 s of that ends the trial (nothing would change)."""
    from runtime.config import HW_CONFIG_DIR
    from tools.experiment.trials import STOOD_STILL_END_S, run_trial

    tr = run_trial("stairs", 15.0, 0, None, False, 0.375, HW_CONFIG_DIR / "experiment.yaml",
                   size=0.21, true_state=True)
    assert not tr.fell and tr.footsteps == 0 and tr.halts == 1
    assert tr.duration_s <= STOOD_STILL_END_S + 0.6
    assert any("stood still" in n for n in tr.notes)
