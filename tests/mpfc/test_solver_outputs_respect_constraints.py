"""MpfcSolver outputs: the plan satisfies every constraint of (15) and Section IV-D, and the
returned ALIP trajectory obeys (15b)-(15c)."""

from __future__ import annotations

import numpy as np
from mpfc_test_helpers import solve, with_params

from processes.footstep_search.footholds import yaw_rotation
from processes.mpfc import MpfcSolver
from tools.testbed.mpfc_instances import random_instance


def test_plan_satisfies_dynamics_timing_torque_crossover_and_footholds(params) -> None:
    p = with_params(params, time_limit_ms=10_000.0)
    solver = MpfcSolver(p)
    rng = np.random.default_rng(21)
    checked = 0
    for m in (3, 8, 15):
        for _ in range(4):
            inst = random_instance(rng, solver.model, m)
            solver.reset()
            sol = solve(solver, inst)
            if not sol.has_plan:
                continue
            checked += 1
            rot = yaw_rotation(inst.yaw)
            steps = (sol.footsteps - inst.p_stance) @ rot  # stance frame
            # (15b): x_0 from the linearisation about T*, with the optimised T and u
            a0, b_t, b_u = solver.model.alip.initial_state_linearisation(
                inst.x_alip, inst.t_remaining_s)
            dt = sol.t_remaining_opt_s - inst.t_remaining_s
            assert np.allclose(sol.alip_states[0], a0 + b_t * dt + b_u * sol.ankle_torque_nm)
            # (15c) with 3D footsteps (height does not enter)
            prev = np.zeros(3)
            for n in range(p.horizon_steps):
                pred = solver.model.alip.s2s_step(sol.alip_states[n], prev, steps[n])
                assert np.allclose(pred, sol.alip_states[n + 1], atol=1e-9)
                prev = steps[n]
            # Section IV-D limits
            assert p.t_ss_min_s - 1e-9 <= sol.first_stance_ss_duration_s <= p.t_ss_max_s + 1e-9
            assert abs(sol.ankle_torque_nm) <= p.ankle_torque_max_nm + 1e-6
            sig = -1.0 if inst.stance == "left" else 1.0
            ys = np.concatenate([[0.0], steps[:, 1]])
            for n in range(p.horizon_steps):
                s_n = sig if n % 2 == 0 else -sig
                assert s_n * (ys[n + 1] - ys[n]) >= -1e-7
            for k, i in enumerate(sol.foothold_indices):
                assert inst.footholds[i].contains(sol.footsteps[k], tol=1e-6)
    assert checked >= 6


def test_nominal_walk_on_open_ground_steps_at_the_nominal_width(params) -> None:
    """On one big flat foothold at the nominal orbit, the plan is the nominal gait: the
    lateral step is about the step width l, duration nominal, ankle torque small."""
    from runtime.geometry import Foothold

    solver = MpfcSolver(params)
    model = solver.model
    v = np.array([0.4, 0.0])
    ground = Foothold.from_polygon(np.array([[-3, -3], [3, -3], [3, 3], [-3, 3]], dtype=float))
    step = np.array([v[0] * params.t_s2s_s, -params.step_width_m])  # left stance: step right
    x0 = model.vs.L0 @ step + model.vs.D0 @ v
    x_c = model.expm_a(-0.3) @ x0
    sol = solver.solve(x_c, "left", np.zeros(3), 0.3, v, [ground])
    assert sol.status == "optimal"
    assert np.isclose(sol.footsteps[0, 1], -params.step_width_m, atol=0.02)
    assert np.isclose(sol.footsteps[0, 0], v[0] * params.t_s2s_s, atol=0.03)
    assert np.isclose(sol.footsteps[1, 1] - sol.footsteps[0, 1], params.step_width_m, atol=0.03)
    assert abs(sol.t_remaining_opt_s - 0.3) < 0.01
    assert abs(sol.ankle_torque_nm) < 2.0


def test_a_wider_crossover_margin_keeps_the_feet_that_far_apart_across(params) -> None:
    """``set_crossover_margin``: stepping to a stop the node asks 10 cm across instead of the
    gait's 6 (``STOP_CROSSOVER_M``: the OSC stands only on feet 7 cm or more apart). At rest
    over the left foot the right foot goes to the margin, whichever it is, and back."""
    import dataclasses

    from processes.mpfc.process import STOP_CROSSOVER_M
    from runtime.geometry import Foothold

    p = dataclasses.replace(params, crossover_margin_m=0.06)
    solver = MpfcSolver(p)
    ground = Foothold.from_polygon(np.array([[-3, -3], [3, -3], [3, 3], [-3, 3]], dtype=float))
    at_rest = np.zeros(4)  # the CoM over the left foot, still
    for margin in (0.06, STOP_CROSSOVER_M, 0.06):
        solver.reset()
        solver.set_crossover_margin(margin)
        sol = solver.solve(at_rest, "left", np.zeros(3), 0.3, np.zeros(2), [ground])
        assert sol.status == "optimal"
        assert np.isclose(sol.footsteps[0, 1], -margin, atol=1e-3), (margin, sol.footsteps)
