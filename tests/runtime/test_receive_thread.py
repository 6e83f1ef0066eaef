"""A loop with a receive thread (``Node.receive_thread``) keeps taking messages into its
buffers while its tick is busy, and ticks on the newest one: the camera polling thread and the
mapping thread of the perception process, over real LCM."""

from __future__ import annotations

import threading
import time
from typing import Any

from lcmtypes import command_t
from runtime.bus import Bus
from runtime.loops import LiveRunner
from runtime.node import Node
from tests.conftest import wait_for
from tests.state_estimator.scripted import live_configs


class SlowMapper(Node):
    """Takes 80 ms per tick; records, per tick, which message it got and how many messages
    its input port had received when the tick began and when it ended."""

    name = "slow_mapper"
    inputs = {"frame": command_t}
    outputs: dict[str, Any] = {}
    trigger_role = "frame"

    def __init__(self, threaded: bool) -> None:
        self.receive_thread = threaded
        self.port: Any = None
        self.ticks: list[tuple[int, int, int]] = []

    def tick(self, ctx: Any, inbox: Any) -> None:
        msg = inbox.trigger()
        before = self.port.received
        time.sleep(0.08)
        self.ticks.append((int(msg.header.seq), before, self.port.received))


def _run(lcm_url: str, threaded: bool) -> SlowMapper:
    ch = f"TEST_RX_FRAME_{int(threaded)}"
    proc, profile = live_configs("slow_mapper", "tests", lcm_url, inputs={"frame": ch},
                                 outputs={})
    node = SlowMapper(threaded)
    runner = LiveRunner(node, proc, profile)
    node.port = runner.ports["frame"]
    thread = threading.Thread(target=runner.run, daemon=True)
    bus = Bus(lcm_url, source="test")
    thread.start()
    try:
        time.sleep(0.2)
        for k in range(30):  # 30 frames at 100 Hz, while each tick takes 80 ms
            msg = command_t()
            msg.header.utime = 1000 * (k + 1)
            bus.publish(ch, msg)  # the bus stamps header.seq = k
            time.sleep(0.01)
        wait_for(lambda: bool(node.ticks) and node.ticks[-1][0] == 29, 3.0, what="last frame")
    finally:
        runner.stop()
        thread.join(2.0)
        bus.close()
    return node


def test_receive_thread_takes_frames_while_the_tick_runs_and_ticks_on_the_newest(lcm_url):
    node = _run(lcm_url, threaded=True)
    # during the busy ticks the receive thread kept filing frames into the buffer
    assert any(after > before for _, before, after in node.ticks[:-1]), node.ticks
    # newest-first: far fewer ticks than frames, and the last tick is on the last frame
    assert 2 <= len(node.ticks) <= 8
    assert node.ticks[-1][0] == 29
    assert node.port.received == 30
    assert node.port.stale_skipped >= 20


def test_without_it_nothing_arrives_while_the_tick_runs(lcm_url):
    node = _run(lcm_url, threaded=False)
    # single-threaded, the loop only reads the socket between ticks
    assert all(after == before for _, before, after in node.ticks), node.ticks
    assert node.ticks[-1][0] == 29
