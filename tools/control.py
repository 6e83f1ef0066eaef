"""procman-style control of a running launch, from another terminal.

* ``cassie list [PROFILE]``: the profiles in hw_config/, or one profile's processes (host,
  module, rate, what it does).
* ``cassie order {start,stop,restart} PROCESS``: the order goes to the launch's supervisor
  over ``SUPERVISOR_ORDERS`` (the process name, or ``*`` for all), and the command waits for
  the supervisor's status to show it done (a restart: a new pid, the restart counted, ready).
* ``cassie logs PROCESS [-f]``: a process's log of the running launch (the folder its
  supervisor reports; else the newest launch's), followed as it grows with ``-f``.

The supervisor is found on the profile's LCM URL (``$CASSIE_LCM_URL`` moves it, as for the
launch itself).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from lcmtypes import supervisor_orders_t, supervisor_status_t
from runtime.bus import Bus
from runtime.config import HW_CONFIG_DIR, find_profile, is_profile, load_profile
from runtime.supervisor import ORDERS, logs_home


def _status(bus: Bus, channel: str, timeout_s: float) -> supervisor_status_t | None:
    sub = bus.subscribe(channel, supervisor_status_t, policy="newest")
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        bus.drain(0.1)
        if (msg := sub.latest()) is not None:
            return msg
    return None


def _bus(profile_arg: str) -> tuple[Bus, str, str]:
    profile = load_profile(find_profile(profile_arg))
    return Bus(profile.lcm_url, source="cassie-order"), profile.status_channel, \
        profile.orders_channel


def cmd_list(argv: list[str]) -> int:
    p = argparse.ArgumentParser(prog="cassie list", description="profiles, or a profile's "
                                "processes")
    p.add_argument("profile", nargs="?", help="a profile name or path: list its processes")
    args = p.parse_args(argv)
    if args.profile is None:
        for path in sorted(HW_CONFIG_DIR.glob("*.yaml")):
            if not is_profile(path):  # channels.yaml, hosts.yaml, processes.yaml...
                continue
            prof = load_profile(path)
            print(f"{prof.name:<16} {prof.mode:<9} {', '.join(prof.launch)}")
        return 0
    prof = load_profile(find_profile(args.profile))
    print(f"profile {prof.name} ({prof.mode}, {prof.path})")
    for name in prof.launch:
        pc = prof.processes[name]
        rate = f"{pc.rate_hz:g} Hz" if pc.rate_hz else "-"
        print(f"  {name:<16} {pc.host:<10} {rate:>8}  {pc.description}")
    return 0


def cmd_order(argv: list[str]) -> int:
    p = argparse.ArgumentParser(prog="cassie order", description="start, stop or restart one "
                                "process of a running launch (procman's deputy orders)")
    p.add_argument("order", choices=ORDERS)
    p.add_argument("process", help="a process name, or '*' for all")
    p.add_argument("--profile", default="sim", help="the launch's profile (for its LCM URL)")
    p.add_argument("--timeout", type=float, default=30.0, help="how long to wait for it, s")
    args = p.parse_args(argv)
    bus, status_ch, orders_ch = _bus(args.profile)
    before = _status(bus, status_ch, 3.0)
    if before is None:
        print(f"no supervisor answers on {bus.url}: is a launch of {args.profile} running "
              "(and CASSIE_LCM_URL the same as its)?", file=sys.stderr)
        return 3
    procs = {q.name: q for q in before.processes}
    if args.process != "*" and args.process not in procs:
        print(f"{args.process!r} is not a process of this launch ({', '.join(procs)})",
              file=sys.stderr)
        return 2
    msg = supervisor_orders_t()
    msg.process, msg.order = args.process, args.order
    bus.publish(orders_ch, msg)
    t0 = time.monotonic()
    first_seq = before.header.seq  # only a status sent after the order says it is done
    names = list(procs) if args.process == "*" else [args.process]
    want = {"stop": ("stopped",), "start": ("ready",), "restart": ("ready",)}[args.order]
    while time.monotonic() - t0 < args.timeout:
        now = _status(bus, status_ch, 1.5)
        if now is None or now.header.seq <= first_seq + 1:
            continue
        cur = {q.name: q for q in now.processes}
        done = all(cur[n].state in want and (args.order != "restart"
                                            or cur[n].pid != procs[n].pid) for n in names)
        if done:
            for n in names:
                q = cur[n]
                print(f"{n}: {args.order} done in {time.monotonic() - t0:.1f} s: {q.state}, "
                      f"pid {procs[n].pid} -> {q.pid}, restarts {q.restarts}")
            return 0
    print(f"{args.order} of {args.process} not done within {args.timeout:.0f} s "
          "(see `cassie logs` and the launch's status table)", file=sys.stderr)
    return 1


def cmd_logs(argv: list[str]) -> int:
    p = argparse.ArgumentParser(prog="cassie logs", description="a process's log of the "
                                "running (or newest) launch")
    p.add_argument("process")
    p.add_argument("-f", "--follow", action="store_true", help="keep printing as it grows")
    p.add_argument("--profile", default="sim", help="the launch's profile (for its LCM URL)")
    p.add_argument("--launch", type=Path, default=None, help="the launch's log folder")
    args = p.parse_args(argv)
    folder = args.launch
    if folder is None:
        bus, status_ch, _ = _bus(args.profile)
        st = _status(bus, status_ch, 2.0)
        if st is not None and st.log_dir:
            folder = Path(st.log_dir)
        else:
            launches = sorted((d for d in logs_home().glob("*") if d.is_dir()),
                              key=lambda d: d.stat().st_mtime)
            if not launches:
                print(f"no launch is running and none has logged under {logs_home()}",
                      file=sys.stderr)
                return 2
            folder = launches[-1]
    path = folder / f"{args.process}.log"
    if not path.exists():
        have = ", ".join(sorted(x.stem for x in folder.glob("*.log")))
        print(f"no log {path} (this launch has: {have})", file=sys.stderr)
        return 2
    print(f"==> {path} <==", file=sys.stderr)
    with open(path, errors="replace") as f:
        sys.stdout.write(f.read())
        sys.stdout.flush()
        try:
            while args.follow:
                line = f.readline()
                if line:
                    sys.stdout.write(line)
                    sys.stdout.flush()
                else:
                    time.sleep(0.2)
        except KeyboardInterrupt:
            return 0
    return 0
