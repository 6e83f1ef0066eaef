"""Defence in depth (issue 14, fault 4): with the OSC's edge checks switched off, a NaN state
or a NaN plan reaches the controller mid-walk. It used to latch safe mode for good and the
robot fell; now it damps for ``safety.recover_s`` (10 ms), then walks on the fresh plan."""

from __future__ import annotations

import copy
import math
from typing import Any

import pytest

from runtime.config import HW_CONFIG_DIR, load_profile
from runtime.harness import Harness
from runtime.node import HEALTH_OK

pytestmark = pytest.mark.faults


def _nan(msg: Any, field: str) -> Any:
    m = copy.deepcopy(msg)
    vals = list(getattr(m, field))
    vals[0] = math.nan
    setattr(m, field, vals)
    return m


@pytest.fixture(scope="module")
def walk() -> dict[str, Any]:
    """5 s of walking; a NaN state at 2 s and 2.5 s, a NaN plan at 3 s and 3.5 s, unchecked."""
    h = Harness.from_profile(load_profile(HW_CONFIG_DIR / "experiment.yaml"))
    nodes = {b.node.name: (i, b.node) for i, b in enumerate(h.bindings)}
    for port in h._ports[nodes["osc"][0]].values():
        port.check = None  # the controller sees what arrives
    newest: dict[str, Any] = {}
    h.tap("CASSIE_STATE", lambda _t, m: newest.__setitem__("state", m))
    h.tap("NETWORK_MPFC_PLAN", lambda _t, m: newest.__setitem__("plan", m))
    modes: list[int] = []
    h.tap("OSC_TORQUE", lambda _t, m: modes.append(int(m.mode)))
    for t_us, channel, role, field in ((2_000_000, "CASSIE_STATE", "state", "q"),
                                       (2_500_000, "CASSIE_STATE", "state", "q"),
                                       (3_000_000, "NETWORK_MPFC_PLAN", "plan",
                                        "stance_foot_world"),
                                       (3_500_000, "NETWORK_MPFC_PLAN", "plan",
                                        "stance_foot_world")):
        h.run_until(t_us)
        h.inject(channel, _nan(newest[role], field))
    h.run_until(5_000_000)
    h.close()
    return {"nodes": nodes, "modes": modes}


def test_each_bad_input_is_a_short_safe_mode_that_clears_and_the_robot_walks_on(walk):
    sim, osc = walk["nodes"]["sim"][1], walk["nodes"]["osc"][1]
    assert sim.health() == HEALTH_OK, sim.status()
    assert sim.counters()["walked_m"] > 1.0
    c = osc.counters()
    assert c["safe_entries"] == 4 and c["safe_recoveries"] == 4, c
    assert c["mode"] == 0.0  # walking at the end
    modes = walk["modes"]
    first_walk = modes.index(0)
    safe_ticks = sum(1 for m in modes[first_walk:] if m == 2)
    # four episodes of ~recover_s each at 2 kHz (20 ticks), nothing longer
    assert 4 * 15 <= safe_ticks <= 4 * 30, safe_ticks
