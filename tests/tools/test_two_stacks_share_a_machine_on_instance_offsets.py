"""``--instance N`` (``$CASSIE_INSTANCE``): every port of a profile moves by 20 N, so two
stacks on one machine share none (LCM domains, UDP links), and two launches running at once
each hear only their own processes."""

from __future__ import annotations

import os
import re
from pathlib import Path

import pytest

from lcmtypes import supervisor_status_t
from runtime.bus import Bus
from runtime.config import HW_CONFIG_DIR, load_profile
from runtime.errors import ConfigError
from tests.conftest import PROFILES, cassie


def ports(instance: int, monkeypatch: pytest.MonkeyPatch) -> set[int]:
    monkeypatch.setenv("CASSIE_INSTANCE", str(instance))
    p = load_profile(HW_CONFIG_DIR / "sim_perception.yaml")
    out = {int(u.rsplit(":", 1)[1]) for u in p.domains.values()}
    for proc in p.processes.values():
        for ch in (*proc.inputs.values(), *proc.outputs.values()):
            if ch.udp is not None:
                out.add(ch.udp[1])
    return out


def test_two_instances_share_no_port(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("CASSIE_LCM_URL", raising=False)
    a, b, zero = ports(1, monkeypatch), ports(2, monkeypatch), ports(0, monkeypatch)
    assert len(a) >= 6 and not a & b and not a & zero and not b & zero
    assert {p - 20 for p in a} == zero  # instance 1 is instance 0 moved by 20


def test_a_bad_instance_is_a_clear_error(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("CASSIE_INSTANCE", "two")
    with pytest.raises(ConfigError, match=r"CASSIE_INSTANCE.*an integer 0 \.\. 99"):
        load_profile(HW_CONFIG_DIR / "sim.yaml")


def test_two_launches_at_once_each_hear_only_their_own(lcm_url: str, procs: list,
                                                       tmp_path: Path) -> None:
    base_port = int(lcm_url.rsplit(":", 1)[1])
    sups = []
    for n in (1, 2):
        sups.append(cassie("launch", str(PROFILES / "supervised.yaml"), "--instance", str(n),
                           "--no-live", "--duration", "4", "--log-dir", str(tmp_path / f"i{n}")))
    procs.extend(sups)
    buses = {n: Bus(f"udpm://239.255.76.67:{base_port + 20 * n}", source="test") for n in (1, 2)}
    subs = {n: b.subscribe("SUPERVISOR_STATUS", supervisor_status_t, policy="each")
            for n, b in buses.items()}
    outs = [s.communicate(timeout=120)[0] for s in sups]
    for out in outs:
        assert "result: ok" in out, out[-2000:]
        # each supervisor took only its own processes' TIMING (none refused as foreign)
        assert not re.search(r"ignored: \d+ TIMING", out), out[-2000:]
    for n, b in buses.items():
        b.drain(0.2)
        seen = []
        while (m := subs[n].pop()) is not None:
            seen.append(m)
        assert seen, f"no status of instance {n} on its port"
        dirs = {m.log_dir for m in seen}
        assert dirs == {str(tmp_path / f"i{n}")}, dirs  # only its own supervisor there
    assert os.environ.get("CASSIE_INSTANCE") is None
