"""max_rate_hz and output_rate_hz count slots of sim time, the same live and in the harness."""

from __future__ import annotations

from lcmtypes import command_t
from runtime.harness import Binding, Harness
from runtime.node import Node, OutputGates, SlotGate
from tests.procs.ticker import Ticker


def test_a_slot_gate_admits_the_first_event_of_each_slot_and_survives_a_lost_one() -> None:
    gate = SlotGate(1000.0)  # 1 ms slots
    states = [0, 500, 1000, 1500, 2000, 3500, 4000, 4500]  # the state at 2.5-3 ms was lost
    assert [u for u in states if gate.admit(u)] == [0, 1000, 2000, 3500, 4000]
    assert gate.admit(100)  # time went backwards (a restarted sim): a new slot


def test_output_gates_decimate_only_the_roles_given() -> None:
    gates = OutputGates({"debug": 100.0})
    sent = [u for u in range(0, 50_000, 500) if gates.admit("debug", u)]
    assert sent == list(range(0, 50_000, 10_000))
    assert gates.dropped == 100 - 5
    assert all(gates.admit("torque", u) for u in range(0, 5000, 500))
    assert gates.due("debug", 60_000) and not gates.due("debug", 40_500)


class Half(Node):
    """Counts its ticks and publishes a debug message each tick."""

    name = "half"
    inputs = {"in": command_t}
    outputs = {"debug": command_t}
    trigger_role = "in"

    def __init__(self) -> None:
        self.ticks = 0
        self.due_seen = 0

    def tick(self, ctx, inbox) -> None:  # type: ignore[no-untyped-def]
        self.ticks += 1
        if ctx.due("debug"):
            self.due_seen += 1
            msg = command_t()
            msg.header.utime = ctx.now_utime
            ctx.publish("debug", msg)


def test_in_the_harness_a_1khz_loop_on_2khz_input_ticks_every_other_message() -> None:
    src = Ticker(None)
    src.period_s = 0.0005  # 2 kHz
    node = Half()
    h = Harness([
        Binding(src, inputs={}, outputs={"out": "IN"}),
        Binding(node, inputs={"in": "IN"}, outputs={"debug": "DEBUG"}, max_rate_hz=1000.0,
                output_rate_hz={"debug": 100.0}),
    ])
    debug: list[int] = []
    h.tap("DEBUG", lambda t, m: debug.append(m.header.utime))
    h.run_until(99_999)  # 200 messages of the 2 kHz source
    assert h.published["IN"] == 200
    assert node.ticks == 100  # one per millisecond
    assert node.due_seen == len(debug) == 10  # 100 Hz
    assert debug == list(range(0, 100_000, 10_000))
