"""`cassie bench launch` attributes CPU to each process by its command line: a process started
as ``cassie run NAME`` (older trees) and as ``python -m runtime.run NAME`` (the supervisor's
way now) are both named NAME, so a side-by-side table compares process with process."""

from __future__ import annotations

import subprocess
import sys
import time

import psutil
import pytest

from tools.benchmarks.launch import _name


@pytest.mark.parametrize("launcher", [["run"], ["-m", "runtime.run"]])
def test_a_stack_process_is_named_after_its_process_entry(launcher):
    # a real process whose command line reads like the launcher's: python -c ... <launcher> osc
    proc = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(30)", *launcher,
                             "osc", "--profile", "hw_config/sim.yaml"])
    try:
        # Popen returns once exec has closed the child's pipes, which can be before the kernel
        # has set the new argument list: until then the command line reads empty, and _name
        # says it does not know yet rather than guess
        deadline = time.monotonic() + 10.0
        while (name := _name(psutil.Process(proc.pid))) is None and time.monotonic() < deadline:
            time.sleep(0.01)
        assert name == "osc"
    finally:
        proc.kill()
        proc.wait()
