"""A machine without a multicast route gets an error that says how to add one."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import uuid

import pytest

from tests.conftest import REPO

needs_netns = pytest.mark.skipif(
    os.geteuid() != 0 or shutil.which("ip") is None,
    reason="needs root and iproute2 to make a network namespace without routes",
)


def _in(ns: str, *cmd: str) -> subprocess.CompletedProcess[str]:
    """``cmd`` run in the network namespace ``ns``, from the repository, its output kept."""
    return subprocess.run(["ip", "netns", "exec", ns, *cmd], cwd=REPO, capture_output=True,
                          text=True, timeout=60)


@needs_netns
def test_missing_multicast_route_gives_error_with_the_fix():
    ns = f"cassie-noroute-{uuid.uuid4().hex[:8]}"
    subprocess.run(["ip", "netns", "add", ns], check=True)
    try:
        subprocess.run(["ip", "netns", "exec", ns, "ip", "link", "set", "lo", "up"], check=True)
        code = "from runtime.bus import Bus\nBus('udpm://239.255.76.67:7667')\n"
        res = _in(ns, sys.executable, "-c", code)
        assert res.returncode != 0
        assert "MulticastRouteError" in res.stderr
        assert "ip route add 224.0.0.0/4 dev lo" in res.stderr
        # and through the CLI: a clear message and exit code 3, no traceback
        res = _in(ns, sys.executable, "-m", "tools.cli", "run", "ticker", "--profile",
                  "tests/profiles/runtime.yaml")
        assert res.returncode == 3
        assert "ip route add 224.0.0.0/4 dev lo" in res.stderr
        assert "Traceback" not in res.stderr
        # with the route added, the same bus comes up
        subprocess.run(
            ["ip", "netns", "exec", ns, "ip", "route", "add", "224.0.0.0/4", "dev", "lo"],
            check=True,
        )
        res = _in(ns, sys.executable, "-c", code)
        assert res.returncode == 0, res.stderr
    finally:
        subprocess.run(["ip", "netns", "del", ns], check=False)
