"""``cassie replay LOG --into s3``: a lockstep walk with perception recorded with ``--log``
and replayed into S3 in the deterministic harness gives, for every elevation map in the
log, the same foothold set the live S3 published (headers aside). Slow (a ~1.5 min launch):
``pytest -m slow``."""

from __future__ import annotations

from pathlib import Path

import lcm
import pytest

from lcmtypes import foothold_set_t
from tests.conftest import cassie
from tools.replay import replay

pytestmark = pytest.mark.slow


def _bare(m: foothold_set_t) -> bytes:
    m.header.seq, m.header.send_mono_ns, m.header.source = 0, 0, ""
    return m.encode()


def test_replayed_maps_give_the_live_foothold_sets(lcm_url: str, procs: list,
                                                   tmp_path: Path) -> None:
    logs = tmp_path / "logs"
    # (an instance of its own: its UDP ports never meet another stack on this machine)
    sup = cassie("launch", "sim_perception", "mode:=lockstep", "--instance", "4", "--log",
                 "--no-live", "--duration", "12", "--log-dir", str(logs))
    procs.append(sup)
    out, _ = sup.communicate(timeout=600)
    assert "result: ok" in out, out[-2000:]
    live = {}
    for e in lcm.EventLog(str(logs / "lcm.log"), "r"):
        if e.channel == "FOOTHOLDS":
            m = foothold_set_t.decode(e.data)
            live[m.header.utime] = _bare(m)
    got = replay(logs / "lcm.log", logs / "sim_perception.overrides.yaml", ["s3"],
                 tmp_path / "s3.log", progress=False)
    again = {m.header.utime: _bare(m) for m in got["FOOTHOLDS"]}
    both = set(live) & set(again)
    print(f"live {len(live)}, replayed {len(again)}, both {len(both)}")
    assert len(live) >= 50 and len(both) >= 0.9 * len(live)
    assert all(live[u] == again[u] for u in both), "a replayed foothold set differs"
