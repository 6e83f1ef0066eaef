"""`cassie bench bridge` runs the real bridge under the live runner, fed over LCM with 2 kHz
states and 1 kHz commands (sim.yaml's OSC rate), with its UDP sink: figures come out and the
sink gets a packet for nearly every state (each command at once, the states between them
filled in with the newest torque; a message that finds a newer one behind it is skipped, as
the loop's newest-message policy says); no timing is judged."""

from __future__ import annotations

import json
from pathlib import Path

from tools.benchmarks import bridge as bench


def test_the_live_bridge_bench_reports_figures_and_every_state_gets_a_packet(
        tmp_path: Path) -> None:
    out = tmp_path / "bridge.json"
    assert bench.main(["--seconds", "1", "--warmup", "0.3", "--repeats", "1", "--contend", "0",
                       "--json", str(out)]) == 0
    fig = json.loads(out.read_text())
    assert fig["ticks"] > 500 and 1500 < fig["rate_hz"] < 2500  # commands and filled states
    assert 0 < fig["cpu_share"] < 2
    assert 0 < fig["tick_cpu_median_ms"] <= fig["tick_cpu_p99_ms"]
    assert fig["feeder_published"] > 1000
    assert 0.9 * fig["feeder_published"] <= fig["sink_received"] <= 1.1 * fig["feeder_published"]
    assert fig["clamps"] > 0 and fig["nan_rejects"] == 0
