"""UDP loss between the sim and the NUC (issue 14): 5 % and 20 % of the datagrams each way
dropped by the kernel, in lockstep and in real time. Cassie must not fall, both ends must
count the loss (the sender's packets against the receiver's, in ``cassie report``), and in
real time, where a lost torque costs nothing but its 0.5 ms, it must walk on.

The loss is the UDP layer's (``$CASSIE_UDP_LOSS``: each receiving socket, the estimator's and
the sim's, has a BPF filter that drops that share at random before the socket sees it); this
machine's kernel has neither netem nor iptables, and the filter drops exactly what a lossy
wire would, unseen by the process. Slow (~1 min each): ``pytest -m faults``.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from runtime.config import HW_CONFIG_DIR
from runtime.udp import LOSS_ENV
from tests.conftest import cassie
from tools.report import analyse, load_budgets

pytestmark = [pytest.mark.faults, pytest.mark.slow]

SECONDS = 30
#: (mode, loss): the least each run must walk (m). In lockstep a loss costs one resend
#: timeout, which follows the chain's measured ~0.65 ms round trip (ResendTimer: 1-10 ms);
#: measured 5.96 m at 5 % and 1.11-1.73 m at 20 % each way (0.03 m with a fixed 10 ms)
MIN_WALK_M = {("realtime", 0.05): 5.0, ("realtime", 0.20): 5.0,
              ("lockstep", 0.05): 2.0, ("lockstep", 0.20): 0.5}


@pytest.mark.parametrize("loss", [0.05, 0.20], ids=["5%", "20%"])
@pytest.mark.parametrize("mode", ["lockstep", "realtime"])
def test_udp_loss_each_way_is_walked_through_and_counted_on_both_ends(
    mode: str, loss: float, lcm_url: str, procs: list, tmp_path: Path
) -> None:
    profile_path = tmp_path / f"loss_{mode}.yaml"
    profile_path.write_text(f"include: [{HW_CONFIG_DIR / 'sim.yaml'}]\n"
                            f"profile: loss_{mode}\nmode: {mode}\n"
                            "launch: [sim, state_estimator, torque_bridge, osc, mpfc]\n")
    logs = tmp_path / "logs"
    env = {LOSS_ENV: str(loss)}  # the supervisor hands it on to every process
    sup = cassie("launch", str(profile_path), "--duration", str(SECONDS), "--no-live",
                 "--log", "--log-dir", str(logs), env=env)
    procs.append(sup)
    out, _ = sup.communicate(timeout=SECONDS + 300)
    summary = out[out.find("summary of profile"):]
    print(summary)
    assert "FELL" not in summary, summary
    walked = re.search(r"robot: walked (-?[0-9.]+) m", summary)
    assert walked is not None, summary
    assert float(walked.group(1)) >= MIN_WALK_M[(mode, loss)], summary
    report = analyse(logs / "lcm.log", load_budgets(HW_CONFIG_DIR / "budgets.yaml"))
    links = report["realtime"]["link"]
    print(json.dumps(links, indent=1))
    assert len(links) == 2, links
    for name, link in links.items():
        # the sender's count against the receiver's: the loss as dropped, within the noise
        # of a few thousand datagrams (lockstep resends count as sent)
        assert 0.5 * loss <= link["lost_ratio"] <= 1.6 * loss, (name, link)
