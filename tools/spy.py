"""`cassie spy [PROFILE]`: LCM's own lcm-spy on a profile's buses, with the stack's types on
its classpath so it decodes every channel (the jar is built once: `cassie types`).

A profile spreads its channels over several LCM domains (the network's and each host's own,
``hw_config/hosts.yaml``), and one lcm-spy listens on one URL: one window per domain is
started (``--domain`` for one). lcm-spy is a Swing window: it needs a display (``DISPLAY``,
or ``ssh -X``); ``--print`` says what would run, for a machine without one.
"""

from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
from pathlib import Path

from runtime.config import HW_CONFIG_DIR, load_profile
from tools.types import _tool, build_java, cache_dir


def classpath() -> str:
    """The stack's types for lcm-spy (built if missing), before what ``CLASSPATH`` held."""
    jar = str(build_java(cache_dir()))
    extra = os.environ.get("CLASSPATH", "")
    return jar + (os.pathsep + extra if extra else "")


def domain_urls(profile_path: Path) -> dict[str, str]:
    """Each LCM domain of the profile and its URL (``$CASSIE_LCM_URL`` moves the network's)."""
    profile = load_profile(profile_path)
    urls = {"network": profile.lcm_url}
    urls.update(profile.domains)
    return dict(sorted(urls.items()))


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="cassie spy", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("profile", nargs="?", type=Path, default=HW_CONFIG_DIR / "sim.yaml",
                   help="the launch profile whose buses to watch (default hw_config/sim.yaml)")
    p.add_argument("--domain", help="only this domain (network, or a host: nuc, laptop...)")
    p.add_argument("--print", dest="dry", action="store_true",
                   help="print the classpath and each lcm-spy command instead of running them")
    args = p.parse_args(argv)
    urls = domain_urls(args.profile)
    if args.domain is not None:
        if args.domain not in urls:
            p.error(f"--domain {args.domain!r}: this profile's domains are {', '.join(urls)}")
        urls = {args.domain: urls[args.domain]}
    cp = classpath()
    cmds = {d: [_tool("lcm-spy"), f"--lcm-url={u}"] for d, u in urls.items()}
    if args.dry:
        print(f"CLASSPATH={cp}")
        for d, cmd in cmds.items():
            print(f"{d}: {' '.join(cmd)}")
        return 0
    if not os.environ.get("DISPLAY") and not os.environ.get("WAYLAND_DISPLAY"):
        print("lcm-spy is a window and there is no display here (DISPLAY is unset): run it "
              "where there is one (or ssh -X); `cassie spy --print` shows the commands",
              file=sys.stderr)
        return 2
    env = dict(os.environ, CLASSPATH=cp)
    # each lcm-spy (a Python launcher and its JVM) in a process group of its own, ended as a
    # whole: a SIGTERM to the launcher alone leaves the JVM and its window behind
    spies = [subprocess.Popen(cmd, env=env, start_new_session=True) for cmd in cmds.values()]
    for d, u in urls.items():
        print(f"lcm-spy on {d} ({u})")
    # a SIGTERM (kill, a script's cleanup) closes the windows too, as Ctrl-C does
    signal.signal(signal.SIGTERM, _interrupt)
    try:
        return max(s.wait() for s in spies)
    except KeyboardInterrupt:
        for s in spies:
            try:
                os.killpg(s.pid, signal.SIGTERM)
            except ProcessLookupError:
                pass  # (that window was closed already)
        for s in spies:
            s.wait()
        return 130


def _interrupt(signum: int, frame: object) -> None:
    """A signal handler that stops the spies as Ctrl-C does."""
    raise KeyboardInterrupt


if __name__ == "__main__":
    raise SystemExit(main())
