"""Project-level promises: CI runs exactly the README's test command."""

from __future__ import annotations

import re

from tests.conftest import REPO


def test_ci_runs_exactly_the_readme_test_command():
    readme = (REPO / "README.md").read_text()
    block = re.search(r"```bash\n(.*?)```", readme, re.S)
    assert block, "README.md lost its set-up block"
    commands = [line.split("#")[0].strip() for line in block.group(1).splitlines()]
    commands = [c for c in commands if c]
    assert len(commands) == 2, f"README.md should give two set-up commands, not {commands}"
    install, test = commands
    ci = (REPO / ".ci" / "run").read_text()
    ci_lines = [
        line.strip() for line in ci.splitlines() if line.strip() and not line.startswith("#")
    ]
    assert ci_lines[-1] == test, f".ci/run ends with {ci_lines[-1]!r}, README says {test!r}"
    assert "pip install --quiet -e '.[dev]'" in ci and install == "pip install -e '.[dev]'"
