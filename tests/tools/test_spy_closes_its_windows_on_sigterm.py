"""``cassie spy`` ended by a SIGTERM (a script's cleanup, ``kill``) closes every lcm-spy it
started, the JVM under each lcm-spy launcher included: nothing is left behind with no parent.
lcm-spy is stood in for by a launcher script that starts a child and waits, as LCM's does."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

from tests.conftest import PROFILES

REPO = PROFILES.parent.parent


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    # a zombie (ended, not yet reaped by its new parent) counts as gone
    with open(f"/proc/{pid}/stat") as f:
        return f.read().split(")")[-1].split()[0] != "Z"


def test_a_sigterm_ends_each_lcm_spy_and_the_program_under_it(tmp_path: Path) -> None:
    pidfile = tmp_path / "jvm.pid"
    fake = tmp_path / "lcm-spy"
    fake.write_text(f"#!/bin/sh\nsleep 300 &\necho $! > {pidfile}\nwait\n")
    fake.chmod(0o755)
    run = textwrap.dedent(f"""
        import sys
        import tools.spy as spy
        spy._tool = lambda name: {str(fake)!r}
        spy.classpath = lambda: ""
        sys.exit(spy.main([{str(REPO / "hw_config" / "sim.yaml")!r}, "--domain", "network"]))
    """)
    log = tmp_path / "spy.txt"
    # (its output to a file: a pipe would stay open as long as anything it started lives)
    with log.open("w") as out:
        p = subprocess.Popen([sys.executable, "-c", run], cwd=REPO, stdout=out,
                             stderr=subprocess.STDOUT, env={**os.environ, "DISPLAY": ":99"})
    try:
        for _ in range(200):
            if pidfile.exists() and pidfile.read_text().strip():
                break
            time.sleep(0.05)
        jvm = int(pidfile.read_text())
        assert _alive(jvm)
        p.send_signal(signal.SIGTERM)
        p.wait(timeout=20)
        assert p.returncode == 130, log.read_text()
        for _ in range(100):
            if not _alive(jvm):
                break
            time.sleep(0.05)
        assert not _alive(jvm), "the program under the lcm-spy launcher outlived cassie spy"
    finally:
        if p.poll() is None:
            p.kill()
        if pidfile.exists() and pidfile.read_text().strip():
            try:  # (what a failing run left behind)
                os.kill(int(pidfile.read_text()), signal.SIGKILL)
            except ProcessLookupError:
                pass
