"""Timing tests measure the live system in real-time mode and write their figures as JSON.

They run only with `pytest -m timing` (never in the default CI run: the machines are shared and
their tails vary 3-10x between runs). Figures go to $CASSIE_TIMING_DIR (default logs/timing/).
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path

import pytest

from tests.conftest import REPO
from tools.benchmarks.common import write_json


@pytest.fixture
def record_figures() -> Callable[[str, dict[str, object]], Path]:
    out_dir = Path(os.environ.get("CASSIE_TIMING_DIR", REPO / "logs" / "timing"))

    def record(name: str, figures: dict[str, object]) -> Path:
        path = out_dir / f"{name}.json"
        write_json(path, name, figures)
        print(f"timing figures written to {path}")
        return path

    return record
