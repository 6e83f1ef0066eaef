"""A log replayed with the stock lcm-logplayer keeps its recorded send stamps; a loop fed by
it must not report them as its lateness or its inputs' age (perception once reported a
lateness of 161,608 ms and 181 of 181 deadlines missed): such a trigger is timed from its
arrival and counted, and ``cassie report`` of the replay shows ages under a second."""

from __future__ import annotations

import shutil
import subprocess
import time
from pathlib import Path

import pytest

from runtime.config import HW_CONFIG_DIR, load_profile
from tests.conftest import PROFILES, cassie
from tools.report import analyse, load_budgets

pytestmark = pytest.mark.skipif(shutil.which("lcm-logplayer") is None,
                                reason="needs LCM's lcm-logplayer")


def test_a_loop_fed_by_lcm_logplayer_reports_honest_input_ages(
        lcm_url: str, procs: list, tmp_path: Path) -> None:
    profile = str(PROFILES / "supervised.yaml")
    rec = cassie("launch", profile, "launch:=[ticker, echo]", "--log", "--no-live",
                 "--duration", "3", "--log-dir", str(tmp_path / "rec"))
    procs.append(rec)
    out, _ = rec.communicate(timeout=120)
    assert "result: ok" in out, out[-1500:]
    time.sleep(2.0)  # the recorded stamps are now seconds old on this clock
    replay = cassie("launch", profile, "launch:=[echo]", "echo.depends_on:=[]", "--log",
                    "--no-live", "--duration", "8", "--log-dir", str(tmp_path / "replay"))
    procs.append(replay)
    time.sleep(4.0)  # echo set up and waiting
    prof = load_profile(PROFILES / "supervised.yaml")  # TEST_TICK lives on the nuc's bus
    url = prof.domains.get(prof.channel_domains.get("TEST_TICK", "network"), prof.lcm_url)
    subprocess.run(["lcm-logplayer", f"--lcm-url={url}", "-e", "TEST_TICK",
                    str(tmp_path / "rec" / "lcm.log")], check=True, timeout=60)
    out, _ = replay.communicate(timeout=120)
    assert "result: ok" in out, out[-1500:]
    rep = analyse(tmp_path / "replay" / "lcm.log", load_budgets(HW_CONFIG_DIR / "budgets.yaml"))
    echo = rep["loops"]["echo/echo"]
    print({k: v for k, v in echo.items() if "age" in k or "lateness" in k or k == "ticks"})
    assert echo["ticks"] > 100  # it ran on the replayed ticks
    assert echo["input_age_max_ms"] < 1000.0 and echo["lateness_max_ms"] < 1000.0, echo
    assert echo["deadline_misses"] < 0.05 * echo["ticks"], echo
