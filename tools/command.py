"""`cassie command`: send the operator's velocity command on COMMAND, as Cassie's radio does.

The radio keeps sending; so does this, at --rate Hz until Ctrl-C or --duration, so a late
process (or one restarted by the supervisor) picks the command up.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

from lcmtypes import command_t
from runtime.bus import Bus
from runtime.config import load_profile
from runtime.config_types import Profile
from runtime.errors import ConfigError
from runtime.route import DEFAULT_URL


def _profile(name: str | None) -> Profile | None:
    if name is None:
        try:
            return load_profile("sim")
        except ConfigError:  # no product profile: fall back to the defaults
            return None
    return load_profile(name)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="cassie command", description=__doc__)
    ap.add_argument("--vx", type=float, default=0.375, help="forward velocity, m/s")
    ap.add_argument("--vy", type=float, default=0.0, help="lateral velocity, m/s")
    ap.add_argument("--yaw-rate", type=float, default=0.0, help="rad/s")
    ap.add_argument("--stand", action="store_true", help="ask the robot to stand still")
    ap.add_argument("--rate", type=float, default=20.0, help="how often to resend, Hz")
    ap.add_argument("--duration", type=float, default=None, help="stop after S seconds")
    ap.add_argument("--once", action="store_true", help="send one message and exit")
    ap.add_argument("--profile", default=None, help="profile for the bus URL and channel name")
    args = ap.parse_args(argv)
    for name in ("vx", "vy", "yaw_rate"):
        v = getattr(args, name)
        if v != v or abs(v) > 3.0:
            print(
                f"--{name.replace('_', '-')} {v} is out of range (allowed: -3..3)", file=sys.stderr
            )
            return 2
    prof = _profile(args.profile)
    url = os.environ.get("CASSIE_LCM_URL") or (
        prof.lcm_url if prof else DEFAULT_URL
    )
    channel = prof.channels["command"].name if prof and "command" in prof.channels else "COMMAND"
    bus = Bus(url, source="operator")
    msg = command_t()
    msg.vx, msg.vy, msg.yaw_rate = args.vx, args.vy, args.yaw_rate
    msg.mode = 1 if args.stand else 0
    end = time.monotonic() + args.duration if args.duration else None
    print(
        f"sending vx={args.vx} vy={args.vy} yaw_rate={args.yaw_rate} "
        f"{'stand' if args.stand else 'walk'} on {channel}",
        flush=True,
    )
    try:
        while True:
            bus.publish(channel, msg)
            if args.once or (end is not None and time.monotonic() >= end):
                break
            time.sleep(1.0 / args.rate)
    except KeyboardInterrupt:
        pass
    return 0


if __name__ == "__main__":
    sys.exit(main())
