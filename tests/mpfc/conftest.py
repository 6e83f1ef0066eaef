"""Shared fixtures for the MPFC algorithm tests (the repo root goes on sys.path)."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
for path in (ROOT, Path(__file__).resolve().parent):  # the repo, and mpfc_test_helpers
    if str(path) not in sys.path:
        sys.path.insert(0, str(path))

from processes.mpfc import MpfcParams  # noqa: E402
from processes.mpfc.problem import MpfcModel  # noqa: E402


@pytest.fixture(scope="session")
def params() -> MpfcParams:
    """Hardware parameters of Table V, from hw_config/gains/mpfc.yaml, with absolute foothold
    heights (the generated instances put the stance foot anywhere, not on a foothold) and the
    paper's crossover constraint (margin 0: with ours of 6 cm, leaves of the random instances
    with the stance foot far off every foothold become so nearly infeasible that the
    reference's piqp fails on some)."""
    import dataclasses

    from runtime.params import load

    p = load(MpfcParams, ROOT / "hw_config" / "gains" / "mpfc.yaml", "hardware")
    return dataclasses.replace(p, foothold_anchor_m=0.0, crossover_margin_m=0.0)


@pytest.fixture(scope="session")
def model(params: MpfcParams) -> MpfcModel:
    """Constant matrices for the hardware parameters."""
    return MpfcModel(params)
