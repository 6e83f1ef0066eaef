"""Shared fixtures: an isolated LCM bus per test, and helpers to run real processes."""

from __future__ import annotations

import os
import random
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

REPO = Path(__file__).resolve().parent.parent
PROFILES = REPO / "tests" / "profiles"

if not os.environ.get("MENAGERIE_ROOT"):
    shared = REPO.parent / "shared" / "menagerie"
    if shared.is_dir():
        os.environ["MENAGERIE_ROOT"] = str(shared)


def pytest_sessionstart(session: pytest.Session) -> None:
    """Compile the numba kernels (state estimator, MPFC search, OSC) into their on-disk cache
    once, up front: on a fresh clone the first compile takes ~10 s each, which would otherwise
    land inside the start-up timeout of whichever test first launches one of those processes."""
    from processes.footstep_search.qp_engine import QpEngine
    from processes.footstep_search.search import ExactSearch

    ExactSearch(QpEngine(2))
    if os.environ.get("MENAGERIE_ROOT"):
        from processes.osc.controller import OscController
        from processes.state_estimator.estimator import CassieEstimator

        CassieEstimator()
        OscController()


@pytest.fixture
def lcm_url(monkeypatch: pytest.MonkeyPatch) -> str:
    """A multicast port of this test's own, so concurrent runs and tests never hear each other."""
    url = f"udpm://239.255.76.67:{random.randint(20000, 60000)}"
    monkeypatch.setenv("CASSIE_LCM_URL", url)
    return url


def profile_bus(profile: str | Path, source: str = "test") -> Any:
    """A bus over a profile's LCM domains (each host's own port, and the network), as the
    profile's processes see them: load it after the ``lcm_url`` fixture has set the port."""
    from runtime.bus import Bus
    from runtime.config import load_profile

    return Bus.for_profile(load_profile(profile), source=source)


def one_process_profile(tmp_path: Path, name: str, params: dict[str, Any] | None = None,
                        gains: Callable[[dict[str, Any]], object] | None = None,
                        mode: str = "realtime") -> Path:
    """A profile file in ``tmp_path`` (``one.yaml``, in ``mode``) running only ``name`` of
    hw_config/processes.yaml, its ``params:`` replaced by ``params`` (None: as there) and its
    gains file a copy of the shipped one in ``tmp_path/gains.yaml``, first changed by
    ``gains(doc)``. Load it with ``runtime.config.load_profile`` and build with
    ``runtime.builder.build_node`` (or ``one_process``, ``build_one``, ``config_error``)."""
    import yaml

    hw = REPO / "hw_config"
    block = dict(yaml.safe_load((hw / "processes.yaml").read_text())["processes"][name])
    block.pop("depends_on", None)
    if params is not None:
        block["params"] = params
    doc = yaml.safe_load((hw / block["gains"]).read_text()) or {}
    if gains is not None:
        gains(doc)
    (tmp_path / "gains.yaml").write_text(yaml.safe_dump(doc, sort_keys=False))  # its order
    block["gains"] = str(tmp_path / "gains.yaml")
    profile = {"profile": "one", "include": [str(hw / "hosts.yaml"), str(hw / "channels.yaml")],
               "mode": mode, "processes": {name: block}, "launch": [name]}
    path = tmp_path / "one.yaml"
    path.write_text(yaml.safe_dump(profile))
    return path


def one_process(tmp_path: Path, name: str, params: dict[str, Any] | None = None,
                gains: Callable[[dict[str, Any]], object] | None = None,
                mode: str = "realtime") -> tuple[Any, Any]:
    """(process config, profile) of ``one_process_profile``'s profile, loaded."""
    from runtime.config import load_profile

    profile = load_profile(one_process_profile(tmp_path, name, params, gains, mode))
    return profile.processes[name], profile


def build_one(tmp_path: Path, name: str, params: dict[str, Any] | None = None,
              gains: Callable[[dict[str, Any]], object] | None = None,
              mode: str = "realtime") -> Any:
    """``name``'s node, built from ``one_process``'s profile as a run builds it."""
    from runtime.builder import build_node

    return build_node(*one_process(tmp_path, name, params, gains, mode))


def config_error(tmp_path: Path, name: str, params: dict[str, Any] | None = None,
                 gains: Callable[[dict[str, Any]], object] | None = None,
                 mode: str = "realtime") -> Any:
    """The ``ConfigError`` building ``name`` (``build_one``) stops with; the test fails when
    it builds. Its file is ``tmp_path/one.yaml`` (a param) or ``tmp_path/gains.yaml``."""
    from runtime.errors import ConfigError

    with pytest.raises(ConfigError) as err:
        build_one(tmp_path, name, params, gains, mode)
    return err.value


def assert_names(err: Any, file: Path, key: str, problem: str, allowed: str | None,
                 listing: str | None = None) -> None:
    """``err`` (a ``ConfigError``) names ``file``, the dotted ``key``, a problem that says
    ``problem``, and ``allowed`` exactly; with ``listing``, an unknown key's (``allowed``
    None) allowed list -- every field, alphabetically -- has ``listing`` in it."""
    assert (err.file, err.key) == (str(file), key)
    assert problem in err.problem
    if allowed is None and listing is not None:
        assert err.allowed is not None and listing in err.allowed
    else:
        assert err.allowed == allowed


def cassie(*args: str, env: dict[str, str] | None = None, **kw: Any) -> subprocess.Popen[str]:
    """Start ``cassie ARGS`` as a real child process (its own process group)."""
    e = dict(os.environ)
    e["PYTHONPATH"] = os.pathsep.join([str(REPO), e.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    e.update(env or {})
    return subprocess.Popen(
        [sys.executable, "-m", "tools.cli", *args],
        cwd=REPO,
        env=e,
        text=True,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        start_new_session=True,
        **kw,
    )


def wait_for(
    pred: Callable[[], bool],
    timeout: float,
    poll: Callable[[], object] | None = None,
    what: str = "condition",
) -> None:
    """Poll until ``pred()`` holds, calling ``poll`` (e.g. a bus drain) in between."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if poll is not None:
            poll()
        else:
            time.sleep(0.02)
        if pred():
            return
    raise AssertionError(f"timed out after {timeout:.0f} s waiting for {what}")


@pytest.fixture
def procs() -> Iterator[list[subprocess.Popen[str]]]:
    """Processes a test started; killed (whole group) at teardown whatever happened."""
    started: list[subprocess.Popen[str]] = []
    yield started
    for p in started:
        if p.poll() is None:
            try:
                os.killpg(p.pid, 9)
            except ProcessLookupError:
                pass
            p.wait(timeout=5)
