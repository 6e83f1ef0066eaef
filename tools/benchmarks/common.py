"""Shared pieces of every benchmark: percentile summaries, a readable table, the flat JSON file.

Benchmarks print figures (median, p99, max, ratios); they never assert on time, because the
machines are shared and noisy (tails vary 3-10x between runs).
"""

from __future__ import annotations

import json
import os
import platform
import signal
import socket
import subprocess
import sys
import threading
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path

import numpy as np

#: the repository the benchmarks run from (the tree a ``--baseline`` is read out of)
REPO = Path(__file__).resolve().parents[2]


def free_udp_port() -> int:
    """A UDP port on 127.0.0.1 that nothing is bound to right now."""
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind(("127.0.0.1", 0))
    port = int(s.getsockname()[1])
    s.close()
    return port


def until_sigterm() -> threading.Event:
    """For a benchmark's child process: an event that SIGTERM sets (its stop), after telling
    the parent on stdout that the child is ready."""
    stop = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    print("ready", flush=True)
    return stop


def git_archive(rev: str, paths: Sequence[str] = ()) -> tuple[str, bytes]:
    """(commit, tar of ``paths``: all of it when empty) of git revision ``rev`` of this
    repository; SystemExit with git's reason when ``rev`` is not readable."""
    def git(*args: str) -> bytes:
        return subprocess.run(["git", "-C", str(REPO), *args], check=True,
                              capture_output=True).stdout

    try:
        sha = git("rev-parse", "--verify", f"{rev}^{{commit}}").decode().strip()
        return sha, git("archive", sha, *paths)
    except (OSError, subprocess.CalledProcessError) as exc:
        err = getattr(exc, "stderr", b"") or b""
        what = ", ".join(paths) or "the tree"
        raise SystemExit(f"--baseline {rev}: cannot read {what} at that revision from git "
                         f"({err.decode().strip() or exc}); give a commit of this "
                         "repository") from exc


def extract_tree(rev: str, paths: Sequence[str] = ()) -> Path:
    """``paths`` (all when empty) of git revision ``rev`` in a temporary folder, removed when
    the benchmark ends."""
    import atexit
    import io
    import shutil
    import tarfile
    import tempfile

    _, tar = git_archive(rev, paths)
    root = Path(tempfile.mkdtemp(prefix="cassie-bench-baseline-"))
    atexit.register(shutil.rmtree, root, True)
    with tarfile.open(fileobj=io.BytesIO(tar)) as tf:
        tf.extractall(root, filter="data")
    return root


def machine_description() -> str:
    """One line naming the machine the figures were measured on."""
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as f:
            for line in f:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    mem_gib = 0.0
    try:
        mem_gib = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") / 2**30
    except (ValueError, OSError):
        pass
    return (
        f"{cpu}; {os.cpu_count()} cores; {mem_gib:.0f} GiB; "
        f"Python {sys.version.split()[0]}; {platform.system()} {platform.release()}"
    )


def summarize(
    samples: Iterable[float] | np.ndarray, prefix: str, unit: str = "ms"
) -> dict[str, float]:
    """Mean, median, p99, p99.9 and max of `samples`, keyed `{prefix}_{stat}_{unit}`."""
    a = np.asarray(list(samples) if not isinstance(samples, np.ndarray) else samples, dtype=float)
    if a.size == 0:
        return {f"{prefix}_count": 0}
    p50, p99, p999 = np.percentile(a, [50.0, 99.0, 99.9])
    return {
        f"{prefix}_count": int(a.size),
        f"{prefix}_mean_{unit}": float(a.mean()),
        f"{prefix}_median_{unit}": float(p50),
        f"{prefix}_p99_{unit}": float(p99),
        f"{prefix}_p999_{unit}": float(p999),
        f"{prefix}_max_{unit}": float(a.max()),
    }


def print_table(title: str, rows: Mapping[str, object] | Iterable[tuple[str, object]]) -> None:
    """Print `rows` (name -> value) as an aligned two-column table under `title`."""
    items = list(rows.items()) if isinstance(rows, Mapping) else list(rows)
    width = max((len(str(k)) for k, _ in items), default=10)
    print(f"\n{title}\n{'-' * len(title)}")
    for key, value in items:
        if isinstance(value, float):
            text = f"{value:.4g}"
        else:
            text = str(value)
        print(f"  {key!s:<{width}}  {text}")


def write_json(
    path: str | os.PathLike[str] | None, name: str, figures: Mapping[str, object]
) -> None:
    """Write one flat JSON object: `name`, `machine` and the figures (names carry their unit)."""
    if path is None:
        return
    out = {"name": name, "machine": machine_description()}
    for key, value in figures.items():
        if isinstance(value, (np.floating, np.integer)):
            value = value.item()
        out[key] = value
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    Path(path).write_text(json.dumps(out, indent=2, sort_keys=False) + "\n", encoding="utf-8")


class DirectInbox:
    """A ``runtime.node.Inbox`` for calling a node's ``tick`` directly, without a bus:
    ``messages[role]`` is what each input holds (all fresh), the trigger is ``trigger_role``'s."""

    def __init__(self, trigger_role: str) -> None:
        self.trigger_role = trigger_role
        self.messages: dict[str, object] = {}

    def trigger(self) -> object | None:
        return self.messages.get(self.trigger_role)

    def latest(self, role: str) -> object | None:
        return self.messages.get(role)

    def is_fresh(self, role: str) -> bool:
        return role in self.messages

    def newest_raw(self, role: str) -> bytes | None:
        return None  # (messages here are decoded already)
