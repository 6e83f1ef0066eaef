"""The committed Python of lcmtypes/ is exactly what lcm-gen makes from lcmtypes/defs/*.lcm."""

from __future__ import annotations

import filecmp
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from tests.conftest import REPO


def _lcm_gen() -> str:
    exe = Path(sys.executable).parent / "lcm-gen"
    found = str(exe) if exe.exists() else shutil.which("lcm-gen")
    if not found:
        pytest.fail("lcm-gen not found: it ships with the `lcm` package (pip install lcm)")
    return found


def test_generated_python_matches_lcm_sources(tmp_path):
    defs = sorted((REPO / "lcmtypes" / "defs").glob("*.lcm"))
    assert len(defs) >= 18
    subprocess.run([_lcm_gen(), "-p", "--ppath", str(tmp_path), *map(str, defs)], check=True)
    fresh = tmp_path / "lcmtypes"
    generated = sorted(p.name for p in fresh.glob("*.py"))
    committed = sorted(p.name for p in (REPO / "lcmtypes").glob("*.py"))
    assert generated == committed, "regenerate with: lcm-gen -p --ppath . lcmtypes/defs/*.lcm"
    stale = [
        n for n in generated if not filecmp.cmp(fresh / n, REPO / "lcmtypes" / n, shallow=False)
    ]
    assert stale == [], (
        f"stale generated files {stale}: run lcm-gen -p --ppath . lcmtypes/defs/*.lcm"
    )


def test_every_message_carries_utime_sequence_and_send_time():
    import lcmtypes

    top_level = [
        n
        for n in dir(lcmtypes)
        if n.endswith("_t") and n not in ("header_t", "foothold_t", "process_status_t")
    ]
    assert len(top_level) >= 15
    for name in top_level:
        msg = getattr(lcmtypes, name)()
        h = msg.header
        assert {"utime", "seq", "send_mono_ns", "source"} <= set(h.__slots__), name
