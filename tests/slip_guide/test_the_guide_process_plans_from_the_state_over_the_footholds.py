"""The SLIP guide process: from a robot state and a foothold set it publishes a plan of steps
on the footholds, each with its region and time, and the CoM's nominal velocity; without
footholds a plan-less message that says why; in the harness it plans at its rate in sim
time."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from lcmtypes import command_t, guide_plan_t
from runtime.builder import apply_rates, build_node
from runtime.codecs import GUIDE_NO_PLAN, guide_plan_from_msg
from runtime.driver import NodeDriver
from runtime.harness import Binding, Harness
from sim.terrain import foot_eroded, foothold_set_msg
from tests.conftest import one_process
from tests.mpfc.test_mpfc_process_gait import StateReplay
from tools.testbed.slip_scenes import chasm


def _chasm_footholds():  # type: ignore[no-untyped-def]
    return foothold_set_msg(foot_eroded(chasm(), 0.10, 0.02))


def _state(speed: float, utime: int):  # type: ignore[no-untyped-def]
    """A standing Cassie's state at ``utime``, moving forward at ``speed``."""
    replay = StateReplay(speed)
    sent: list = []
    ctx = type("Ctx", (), {"now_utime": utime,
                           "publish": lambda self, role, msg: sent.append(msg)})()
    replay.tick(ctx, None)
    return sent[0]


def test_a_state_and_footholds_give_steps_on_the_footholds_ahead_in_time(tmp_path: Path
                                                                         ) -> None:
    d = NodeDriver.from_config(*one_process(tmp_path, "slip_guide", mode="lockstep"))
    d.tick(utime=500_000, state=_state(0.375, 500_000), footholds=_chasm_footholds())
    plan = guide_plan_from_msg(d.sent["plan"][-1])
    assert plan.ok, plan.status_text
    assert plan.utime == 500_000 and plan.horizon_s == 3.0  # the `guide` variant's horizon
    assert len(plan.positions) >= 3 and plan.qp_solves >= 1 and plan.plan_wall_ms > 0.0
    assert np.all(plan.start_s >= 0.5 - 1e-9) and np.all(plan.end_s > plan.start_s)
    assert np.all(np.diff(plan.start_s) >= -1e-9)  # in the order they begin
    for k, p in enumerate(plan.positions):  # each on its region: the platforms, not the gap
        assert plan.region[k] >= 0
        assert plan.regions[plan.region[k]].contains_xy(p[0], p[1], 1e-6)
    assert max(p[0] for p in plan.positions) > 0.92  # a step beyond the chasm (3 s ahead)
    vx, vy = plan.nominal_velocity
    assert 0.1 < vx < 0.8 and abs(vy) < 0.2


def test_without_footholds_it_says_so_and_the_mpfc_is_left_unguided(tmp_path: Path) -> None:
    d = NodeDriver.from_config(*one_process(tmp_path, "slip_guide", mode="lockstep"))
    d.tick(utime=0, state=_state(0.0, 0))
    msg: guide_plan_t = d.sent["plan"][-1]
    assert msg.status == GUIDE_NO_PLAN and msg.num_steps == 0
    assert msg.status_text == "no footholds yet"
    cmd = command_t()
    cmd.mode = 1  # the radio's stand: a plan at no speed, still over the footholds
    d.tick(utime=250_000, state=_state(0.0, 250_000), footholds=_chasm_footholds(),
           command=cmd)
    assert guide_plan_from_msg(d.sent["plan"][-1]).ok


def test_in_the_harness_it_plans_at_its_rate_in_sim_time(tmp_path: Path) -> None:
    proc, profile = one_process(tmp_path, "slip_guide", mode="lockstep")
    node = build_node(proc, profile)
    apply_rates(node, proc)
    h = Harness([
        Binding(StateReplay(0.3), inputs={}, outputs={"state": "S"}),
        Binding(node, inputs={"state": "S", "footholds": "F", "command": "C"},
                outputs={"plan": "G"}, delay_us=round(proc.harness_delay_ms * 1000)),
    ])
    plans: list[tuple[int, guide_plan_t]] = []
    h.tap("G", lambda t, m: plans.append((t, m)))
    h.inject("F", _chasm_footholds(), at_us=0)
    h.run_until(1_000_000)
    assert proc.rate_hz == 4
    # one plan each 0.25 s, out after the modelled 40 ms, from the newest state then (the
    # replay's, every 5 ms)
    assert [t for t, _ in plans] == [40_000, 290_000, 540_000, 790_000]
    assert all(0 <= t - 40_000 - m.header.utime <= 5_000 for t, m in plans)
    assert sum(m.status == guide_plan_t.STATUS_OK for _, m in plans) >= 3
    assert node.counters()["plans"] >= 3
