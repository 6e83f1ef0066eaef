"""The live stack in real-time mode, measured against the budgets in hw_config/budgets.yaml.

Launches `hw_config/sim.yaml` for a bounded time with the LCM logger, runs `cassie report` on
the log and writes the figures as JSON. Run with `pytest -m timing` on a quiet machine.
"""

from __future__ import annotations

import json

import pytest

from runtime.config import HW_CONFIG_DIR
from tests.conftest import cassie

pytestmark = pytest.mark.timing
SECONDS = 20


def test_every_loop_and_hop_of_the_live_stack_meets_its_budget(
    lcm_url, procs, tmp_path, record_figures
):
    logs = tmp_path / "logs"
    sup = cassie(
        "launch",
        str(HW_CONFIG_DIR / "sim.yaml"),
        "--duration",
        str(SECONDS),
        "--no-live",
        "--log",
        "--log-dir",
        str(logs),
    )
    procs.append(sup)
    out, _ = sup.communicate(timeout=SECONDS + 180)
    assert sup.returncode == 0, out
    rep = cassie("report", str(logs / "lcm.log"), "--json", str(tmp_path / "report.json"))
    procs.append(rep)
    text, _ = rep.communicate(timeout=300)
    print(text)
    assert rep.returncode == 0, text
    figures = json.loads((tmp_path / "report.json").read_text())
    record_figures("timing_stack", figures)
    over = [line for line in text.splitlines() if line.rstrip().endswith("OVER")]
    assert not over, "over budget:\n" + "\n".join(over)
