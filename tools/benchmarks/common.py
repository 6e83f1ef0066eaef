"""Shared pieces of every benchmark: percentile summaries, aligned tables, progress bars,
the flat JSON file.

Benchmarks print figures (median, p99, max, ratios); they never assert on time, because the
machines are shared and noisy (tails vary 3-10x between runs).
"""

from __future__ import annotations

import functools
import io
import json
import os
import platform
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from tqdm import tqdm

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


def machine_load(repeats: int = 100) -> dict[str, float]:
    """How busy the machine is: the 1-minute load average, and the cost (us) of one tiny
    numpy op, the median of ``repeats`` timings (a quiet 2-core VM does ``a + b`` on
    3-vectors in about 0.4-0.5 us; shared, 3-5x more)."""
    a, b = np.zeros(3), np.ones(3)
    samples = []
    for _ in range(repeats):
        t0 = time.perf_counter_ns()
        for _ in range(50):
            np.add(a, b)
        samples.append((time.perf_counter_ns() - t0) / 50 / 1e3)
    return {"load_avg_1min": os.getloadavg()[0], "ref_numpy_op_us": float(np.median(samples))}


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


def _is_terminal(out: IO[str]) -> bool:
    """Whether ``out`` is a terminal (a captured or redirected stream is not)."""
    try:
        return out.isatty()
    except (AttributeError, ValueError):
        return False


def print_columns(columns: Sequence[str], rows: Iterable[Sequence[object]],
                  out: IO[str] | None = None, justify: str | None = None,
                  header: bool = True) -> None:
    """Print ``rows`` under ``columns`` as an aligned table (rich); ``justify`` is one letter
    per column, ``l`` or ``r`` (default: the first left, the others right); a None cell is
    blank. Cells are printed as given, never read as rich markup (``[ms]`` stays ``[ms]``)."""
    from rich import box
    from rich.console import Console
    from rich.table import Table
    from rich.text import Text

    out = sys.stdout if out is None else out  # looked up now: a test's capture sees it
    justify = justify or "l" + "r" * (len(columns) - 1)
    tty = _is_terminal(out)
    encoding = (getattr(out, "encoding", None) or "utf-8").lower()
    # the header's underline as box-drawing characters, or dashes where they cannot be encoded
    line = box.SIMPLE_HEAD if encoding.startswith("utf") else box.Box(
        "    \n    \n -- \n    \n    \n    \n    \n    \n", ascii=True)
    table = Table(box=line if header else None, show_header=header, show_edge=False,
                  pad_edge=False, header_style="bold" if tty else "")
    for name, j in zip(columns, justify, strict=True):
        table.add_column(Text(name), justify="left" if j == "l" else "right")
    for row in rows:
        table.add_row(*(Text("" if c is None else str(c)) for c in row))
    if tty:  # with its styles; never squeezed below its own width (rich would cut or fold
        # cells to fit a narrow terminal): the terminal wraps a line instead, nothing is lost
        console = Console(file=out, highlight=False)
        natural = console.measure(table, options=console.options.update_width(10_000))
        console.width = max(console.width, natural.maximum)
        console.print(table)
        return
    # a log, a pipe or a test: one line per row however wide, no styles, no trailing blanks
    console = Console(file=io.StringIO(), width=10_000, highlight=False, color_system=None)
    with console.capture() as cap:
        console.print(table)
    out.write("".join(ln.rstrip() + "\n" for ln in cap.get().splitlines()))


def print_table(title: str, rows: Mapping[str, object] | Iterable[tuple[object, ...]],
                columns: Sequence[str] | None = None, out: IO[str] | None = None,
                justify: str | None = None) -> None:
    """Print ``rows`` (name -> value, or tuples of cells) as an aligned table under
    ``title``; with ``columns``, a header row of those names (one per cell); ``justify`` as
    ``print_columns``'s (default: every column left)."""
    items = list(rows.items()) if isinstance(rows, Mapping) else [tuple(r) for r in rows]
    out = sys.stdout if out is None else out
    out.write(f"\n{title}\n{'-' * len(title)}\n")

    def cell(value: object) -> str:
        return f"{value:.4g}" if isinstance(value, float) else str(value)

    width = max((len(r) for r in items), default=2)
    cells = [[cell(c) for c in r] + [""] * (width - len(r)) for r in items]
    # the names left, the values left too (a value is often a sentence: "0.1 -> 0.2 (2x)")
    print_columns(columns or [""] * width, cells, out, justify=justify or "l" * width,
                  header=columns is not None)


@functools.cache
def _bar_class() -> type[tqdm]:
    """tqdm without its monitor thread: a thread that wakes every 10 s in a benchmark's
    process is one more thing to preempt what is being timed."""
    from tqdm import tqdm

    class Bar(tqdm):  # type: ignore[type-arg]
        monitor_interval = 0

    return Bar


def progress(total: float | None, desc: str, unit: str = "it", quiet: bool = False,
             **kwargs: Any) -> tqdm:
    """A progress bar with an ETA on stderr for a long loop of a benchmark or tool: drawn
    only on a terminal (off when stderr is piped or captured, or ``quiet``) and redrawn at
    most twice a second, so its cost stays out of what the loop times; gone when closed."""
    return _bar_class()(total=total, desc=desc, unit=unit, file=sys.stderr,
                        disable=True if quiet else None, mininterval=0.5, leave=False,
                        dynamic_ncols=True, **kwargs)


def say(line: str, file: IO[str] | None = None) -> None:
    """Print ``line`` (stdout by default) above any progress bar, not through it."""
    from tqdm import tqdm

    out = sys.stdout if file is None else file
    tqdm.write(line, file=out)
    out.flush()


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

