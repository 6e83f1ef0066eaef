"""``cassie check PROFILE`` (``python -m runtime.check``): build every process of a launch
profile without running it.

Each process's node is made exactly as ``cassie run`` makes it (``runtime.builder``:
its params and gains files read and validated), but never set up or started. Then the
channels the built nodes publish are compared: two processes publishing on one LCM channel
are refused (the subscriber would take both streams as one, and the launch would blame the
wrong process). The supervisor runs this before it starts anything, so a typo or a NaN in
any gains file stops the launch on the terminal, not after a partial start in one log.
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import dataclass

from runtime.builder import build_node, process_module
from runtime.config import load_profile
from runtime.config_types import Profile
from runtime.errors import ConfigError


@dataclass
class Checked:
    """One process's outcome: the node's type, or what is wrong with its configuration."""

    name: str
    node_type: str = ""
    error: str = ""
    seconds: float = 0.0


def check_profile(profile: Profile, names: list[str] | None = None) -> tuple[
        list[Checked], list[str]]:
    """Build each named process of ``profile`` (default: its launch list); return the
    per-process outcomes and the channel collisions found among the built nodes."""
    results: list[Checked] = []
    publishers: dict[tuple[str, str], tuple[str, str]] = {}
    collisions: list[str] = []
    for name in names or list(profile.launch):
        proc = profile.processes[name]
        out = Checked(name)
        results.append(out)
        t0 = time.perf_counter()
        try:
            module = process_module(proc)
            if hasattr(module, "make_node"):
                node = build_node(proc, profile)
                out.node_type = type(node).__name__
                roles = [r for r in node.outputs if r in proc.outputs]
            elif hasattr(module, "check"):  # a main(proc, profile) program that can check
                module.check(proc, profile)
                out.node_type = "main"
                roles = list(proc.outputs)
            else:
                out.node_type = "main (not checked: no check(proc, profile))"
                roles = list(proc.outputs)
        except ConfigError as exc:  # (a main's check too: named where the value was written)
            out.error = str(proc.blame(exc))
            continue
        except Exception as exc:  # whatever a broken file makes a constructor raise
            out.error = f"{type(exc).__name__}: {exc} (building {proc.module}.make_node)"
            continue
        finally:
            out.seconds = time.perf_counter() - t0
        for role in roles:
            ch = proc.outputs[role]
            if ch.is_udp:
                continue
            key = (profile.channel_domains.get(ch.name, "network"), ch.name)
            if key in publishers:
                other, other_role = publishers[key]
                collisions.append(
                    f"{proc.source_file}: processes.{name}.outputs.{role}: channel {ch.name} "
                    f"is already published by {other} (outputs.{other_role}); give one of "
                    "them another channel in hw_config/channels.yaml, or turn that output off")
            else:
                publishers[key] = (name, role)
    return results, collisions


def main(argv: list[str] | None = None) -> int:
    """Print a line per process and exit 2 when any is misconfigured."""
    ap = argparse.ArgumentParser(prog="cassie check", description=__doc__.splitlines()[0])
    ap.add_argument("profile", help="profile name or path, e.g. hw_config/sim.yaml")
    ap.add_argument("--process", action="append", default=None,
                    help="check only this process (repeatable); default: the launch list")
    args = ap.parse_args(argv)
    try:
        profile = load_profile(args.profile)
    except ConfigError as exc:
        print(f"config error: {exc}", file=sys.stderr)
        return 2
    unknown = [n for n in args.process or [] if n not in profile.processes]
    if unknown:
        print(f"config error: no process named {', '.join(unknown)} in {profile.path} "
              f"(known: {', '.join(sorted(profile.processes))})", file=sys.stderr)
        return 2
    results, collisions = check_profile(profile, args.process)
    width = max(len(r.name) for r in results)
    for r in results:
        verdict = f"error: {r.error}" if r.error else f"ok    {r.node_type}"
        print(f"{r.name:<{width}}  {r.seconds:5.2f} s  {verdict}")
    for c in collisions:
        print(f"config error: {c}")
    bad = sum(1 for r in results if r.error) + len(collisions)
    print(f"checked {len(results)} process(es) of profile {profile.name}: "
          + (f"{bad} problem(s)" if bad else "all good"))
    return 2 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
