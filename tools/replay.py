"""`cassie replay LOG --into PROCESS...`: feed a recorded log to processes in the deterministic
harness, on the log's sim time, and record what they answer.

The same node code as live (``make_node`` of the profile's processes, bound to the same
channels, the same edge checks), but stepped in sim-time order in one process
(``runtime.harness``): each logged message on one of their inputs is delivered at the sim
time it carries (``header.utime``), so the answers depend on the log alone, never on how busy
the machine is: a perception or S3 change can be tried on a recorded walk and compared message
for message. Messages on channels the replayed processes publish themselves are left out (they
are what gets recomputed). For a live replay, with the wall clock, use LCM's own
``lcm-logplayer`` into a launch of those processes.

Writes the processes' outputs to ``--out`` (an LCM log whose event times are the sim times, in
microseconds) and prints a count per channel.
"""

from __future__ import annotations

import argparse
import sys
from collections import Counter
from pathlib import Path
from typing import Any

import lcm

from runtime.config import find_profile, load_profile
from runtime.harness import Harness


def _types() -> dict[bytes, type]:
    from tools.report import _types_by_fingerprint

    return _types_by_fingerprint()


def replay(log_path: Path, profile_path: Path, into: list[str],
           out_path: Path | None = None, progress: bool = True) -> dict[str, list[Any]]:
    """Replay ``log_path`` into the processes ``into`` of the profile; returns every message
    they published, per channel, in order (and writes them to ``out_path``)."""
    profile = load_profile(profile_path)
    unknown = [n for n in into if n not in profile.processes]
    if unknown:
        raise SystemExit(f"--into {', '.join(unknown)}: not a process of {profile.name} "
                         f"({', '.join(sorted(profile.processes))})")
    harness = Harness.from_profile(profile, into)
    inputs = {ch for b in harness.bindings for ch in b.inputs.values()}
    outputs = {ch for b in harness.bindings for ch in b.outputs.values()}
    feed = inputs - outputs
    types = _types()
    try:
        log = lcm.EventLog(str(log_path), "r")
    except OSError as exc:
        raise SystemExit(f"cannot read LCM log {log_path}: {exc}") from exc
    events: list[tuple[int, int, str, bytes]] = []
    skipped: Counter[str] = Counter()
    for k, e in enumerate(log):
        if e.channel not in feed:
            continue
        cls = types.get(e.data[:8])
        try:
            utime = int(cls.decode(e.data).header.utime) if cls is not None else -1
        except Exception:  # a malformed logged message: counted, left out
            utime = -1
        if utime < 0:
            skipped[e.channel] += 1
            continue
        events.append((utime, k, e.channel, e.data))
    if not events:
        raise SystemExit(f"nothing in {log_path} on the inputs of {', '.join(into)} "
                         f"({', '.join(sorted(feed)) or 'none'})")
    events.sort()  # sim-time order; ties in log order
    got: dict[str, list[Any]] = {ch: [] for ch in outputs}
    writer = lcm.EventLog(str(out_path), "w", overwrite=True) if out_path else None

    def tap(channel: str):  # type: ignore[no-untyped-def]
        def on(t_us: int, msg: Any) -> None:
            got[channel].append(msg)
            if writer is not None:
                writer.write_event(t_us, channel, msg if isinstance(msg, bytes) else msg.encode())
        return on

    for ch in outputs:
        harness.tap(ch, tap(ch))
    bar = None
    if progress:
        from tqdm import tqdm  # (a well-kept progress bar with an ETA)

        bar = tqdm(total=len(events), unit="msg", desc=f"replay into {', '.join(into)}",
                   file=sys.stderr)
    try:
        for utime, _, channel, data in events:
            harness.run_until(utime - 1)  # everything before this message first
            harness.inject(channel, data, at_us=utime)
            if bar is not None:
                bar.update(1)
        harness.run_until(events[-1][0] + 1_000_000)  # the answers to the last ones
    finally:
        harness.close()
        if bar is not None:
            bar.close()
        if writer is not None:
            writer.close()
    for ch, n in skipped.items():
        print(f"left out {n} message(s) on {ch} without a sim time", file=sys.stderr)
    return got


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="cassie replay", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("log", type=Path, help="an LCM log (cassie launch --log, lcm-logger)")
    p.add_argument("--into", nargs="+", required=True, metavar="PROCESS",
                   help="the processes to feed (e.g. s3, or perception s3)")
    p.add_argument("--profile", default="sim_perception",
                   help="the profile whose processes and channels to use")
    p.add_argument("--out", type=Path, default=None,
                   help="write the outputs to this LCM log (sim-time stamps)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    args = p.parse_args(argv)
    got = replay(args.log, find_profile(args.profile), args.into, args.out,
                 progress=not args.quiet)
    for ch, msgs in sorted(got.items()):
        print(f"{ch:<24} {len(msgs):>7} message(s)")
    if args.out:
        print(f"written to {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
