"""Lockstep: the sim steps only on a command that answers its newest state, so two runs fed
the same commands produce bit-identical states, packets and depth frames."""

from __future__ import annotations

import numpy as np

from runtime.cassie_packets import OutputPacket, encode_input
from runtime.driver import NodeDriver

from .conftest import HW_CONFIG

STEPS = 120


def _commands(seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return rng.uniform(-20.0, 20.0, size=(STEPS, 10))


def _run(driver: NodeDriver, torques: np.ndarray) -> tuple[bytes, list[bytes], list[bytes]]:
    state = OutputPacket()
    for k in range(STEPS):
        state.decode(driver.sent["robot_output"][-1])
        driver.tick(command=encode_input(k, state.seq, torques[k]))
    return (driver.node.core.d.qpos.tobytes(), list(driver.sent["robot_output"]),
            list(driver.sent["depth"]))


def test_two_lockstep_runs_with_the_same_commands_are_identical(driver_factory) -> None:
    params = {"terrain": "terrains/stones.yaml", "terrain_seed": 7}
    gains = HW_CONFIG / "gains" / "sim.yaml"
    a = _run(driver_factory("lockstep", params, gains), _commands(1))
    b = _run(driver_factory("lockstep", params, gains), _commands(1))
    assert len(a[1]) == STEPS + 1 and len(a[2]) >= 2  # depth frames rendered in lockstep too
    assert a == b
    c = _run(driver_factory("lockstep", params, gains), _commands(2))
    assert c[0] != a[0]  # and the state does depend on the commands


def test_lockstep_ignores_stale_answers_and_resends_on_timeout(driver_factory) -> None:
    drv = driver_factory("lockstep", {"terrain": "flat"})
    node = drv.node
    assert node.trigger_role == "command" and node.trigger_timeout_s == 0.01
    first = drv.sent["robot_output"][-1]
    state = OutputPacket().decode(first)
    stale = encode_input(0, (state.seq + 5) & 0xFF, np.zeros(10))  # answers no state of ours
    assert drv.tick(command=stale)
    assert node.core.steps == 0 and node.tpc.unanswered == 1
    assert len(drv.sent["robot_output"]) == 1
    drv.timeout_tick()  # the runner's timeout tick: trigger() is None
    assert node.core.steps == 0 and node.tpc.timeouts == 1
    assert drv.sent["robot_output"][-1] == first  # the same state, sent again
    assert "timeouts=1" in node.status()
    drv.tick(command=encode_input(1, state.seq, np.zeros(10)))
    assert node.core.steps == 1
