"""The floors of docs/architecture.md, checked on the source: robot code (processes/) and the
runtime import nothing from the simulator, the runtime nothing from the tools, and no
process package imports another's shell (its process.py)."""

from __future__ import annotations

import ast
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def _imports(folder: str) -> list[tuple[Path, str]]:
    """(file, imported module) for every import under ``folder``, lazy ones included."""
    out = []
    for path in sorted((REPO / folder).rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                out += [(path, a.name) for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.module and not node.level:
                out.append((path, node.module))
    return out


def _top(module: str) -> str:
    return module.split(".")[0]


def test_processes_and_runtime_import_nothing_from_sim() -> None:
    bad = [f"{p.relative_to(REPO)}: {m}" for folder in ("processes", "runtime")
           for p, m in _imports(folder) if _top(m) == "sim"]
    assert not bad, bad


def test_runtime_imports_nothing_from_tools_or_processes() -> None:
    bad = [f"{p.relative_to(REPO)}: {m}" for p, m in _imports("runtime")
           if _top(m) in ("tools", "processes", "sim")]
    assert not bad, bad


def test_no_process_package_imports_another_process_shell() -> None:
    bad = []
    for p, m in _imports("processes"):
        parts = m.split(".")
        own = p.relative_to(REPO / "processes").parts[0]
        if parts[0] == "processes" and len(parts) > 2 and parts[2] == "process" \
                and parts[1] != own:
            bad.append(f"{p.relative_to(REPO)}: {m}")
    assert not bad, bad
