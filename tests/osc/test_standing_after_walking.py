"""A radio command to stand, mid-walk: Cassie steps to a stop and stands, then walks on.

In the harness (experiment profile, flat ground) the stand is asked at 2 s; the MPFC plans at
velocity 0 and the OSC hands back to the standing controller in double stance once the CoM is
slower than 0.1 m/s. With the standing CoM gains of Table VI style (kp 60, kd 12 in x, y) the
robot fell ~1 s later: stopping a 0.08 m/s sideways drift asked more acceleration than the
stance width gives, the QP put the whole weight on one foot and the other slid. At 6 s the
radio asks to walk again: standing hands over to walking in a double-stance plan.
"""

from __future__ import annotations

from lcmtypes import command_t
from runtime.config import HW_CONFIG_DIR, load_profile
from runtime.harness import Harness
from runtime.node import HEALTH_OK


def test_a_stand_command_mid_walk_stands_and_a_walk_command_walks_on():
    h = Harness.from_profile(load_profile(HW_CONFIG_DIR / "experiment.yaml"))
    sim = next(b.node for b in h.bindings if b.node.name == "sim")
    modes: list[tuple[float, int]] = []
    h.tap("OSC_TORQUE", lambda t, m: modes.append((t * 1e-6, int(m.mode))))
    h.run_until(2_000_000)
    radio = command_t()
    for k in range(120):  # the radio resends at 20 Hz: stand from 2 s, walk from 6 s
        radio.header.utime = 2_000_000 + 50_000 * k
        radio.mode = 1 if radio.header.utime < 6_000_000 else 0
        radio.vx = 0.0 if radio.mode else 0.375
        h.inject("COMMAND", radio, at_us=radio.header.utime)
    h.run_until(5_900_000)
    walked_standing = sim.counters()["walked_m"]
    h.run_until(8_000_000)
    h.close()
    assert sim.health() == HEALTH_OK, sim.status()
    standing = [m for t, m in modes if 4.0 < t < 6.0]
    assert standing and set(standing) == {1}, "not standing after the stand command"
    assert 2 not in {m for _, m in modes}, "safe mode"
    assert [m for t, m in modes if t > 7.5] and {m for t, m in modes if t > 7.5} == {0}
    assert sim.counters()["walked_m"] - walked_standing > 0.3  # walking on after 6 s
