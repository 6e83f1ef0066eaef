"""The ``cassie`` command: launch a profile, run one process, benchmarks, experiments, tools."""

from __future__ import annotations

import argparse
import importlib
import logging
import os
import sys
from pathlib import Path

from runtime.errors import ConfigError, exit_code
from runtime.run import add_arguments as add_run_arguments

BENCHMARKS = ("sim", "estimator", "mpfc", "dcm", "osc", "s3", "lcm", "launch", "bridge",
              "segmenters", "slip")


def _cmd_launch(args: argparse.Namespace) -> int:
    from runtime.config import find_profile, load_profile
    from runtime.supervisor import Helper, Supervisor, new_log_dir

    if args.instance is not None:  # (the processes inherit it with the environment)
        os.environ["CASSIE_INSTANCE"] = str(args.instance)
    log_dir = Path(args.log_dir) if args.log_dir else None
    path = find_profile(args.profile)
    if args.overrides:  # key:=value: a profile of the changes, kept in the launch's logs
        from tools.overrides import write_overlay

        log_dir = log_dir or new_log_dir(load_profile(path).name)
        path = write_overlay(path, args.overrides, log_dir)
        print(f"overrides: {' '.join(args.overrides)} (profile {path})")
    profile = load_profile(path)
    helpers = []
    if args.log or args.dashboard:
        log_dir = log_dir or new_log_dir(profile.name)
    if args.log:
        # every domain (each host's bus and the network) into one log, read in batches so
        # that recording never wakes anyone's CPU per message (tools/logger.py)
        # In lockstep the stack runs flat out at real-time priority and a nice 10 logger
        # starved: 173,563 datagrams (depth frames, maps) lost to full buffers in a 12 s
        # perception run, no map logged at all. There it reads at the lowest FIFO priority
        # (sim time waits a moment; it has no deadline); in real time it stays nice 10,
        # below every loop.
        helpers.append(Helper(
            "logger", (sys.executable, "-m", "tools.cli", "log", str(profile.path),
                       str(log_dir / "lcm.log")),
            nice=10, rt_priority=1 if profile.mode == "lockstep" else None))
    if args.dashboard:
        # started before the stack so it sees everything; it records headless into the log
        # folder, and also opens a viewer where there is a display; it renices itself
        cmd = [sys.executable, "-m", "tools.cli", "dashboard", "--profile", str(profile.path),
               "--save", str(log_dir / "dashboard.rrd")]
        if os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"):
            cmd.append("--spawn")
        helpers.append(Helper("dashboard", tuple(cmd)))
    sup = Supervisor(
        profile,
        log_dir=log_dir,
        duration_s=args.duration,
        live_table=False if args.no_live else None,
        helpers=helpers,
        screen=args.screen,
    )
    return sup.run()


def _cmd_deputy(args: argparse.Namespace) -> int:
    """Serve launches on this host (runtime.deputy): the supervisor orders, this starts."""
    from runtime.config import find_profile, instance, load_profile
    from runtime.deputy import Deputy, deputy_key

    if args.instance is not None:
        os.environ["CASSIE_INSTANCE"] = str(args.instance)
    profile = load_profile(find_profile(args.profile))  # (the bus and the channels' names)
    if args.host not in profile.hosts:
        raise ConfigError(str(profile.path), "hosts", f"no host named {args.host!r}",
                          allowed=", ".join(sorted(profile.hosts)))
    deputy = Deputy(args.host, profile.lcm_url, profile.deputy_orders_channel,
                    profile.deputy_status_channel, deputy_key(create=not args.no_new_key),
                    instance=instance())
    return deputy.run()


def _cmd_run(args: argparse.Namespace) -> int:
    from runtime.run import run_process

    return run_process(args)


def _cmd_bench(args: argparse.Namespace, rest: list[str]) -> int:
    try:
        module = importlib.import_module(f"tools.benchmarks.{args.name}")
    except ModuleNotFoundError as exc:
        if exc.name and exc.name.endswith(args.name):
            print(f"benchmark {args.name!r} is not built yet", file=sys.stderr)
            return 2
        raise
    return int(module.main(rest) or 0)


def _cmd_module(module_name: str, rest: list[str]) -> int:
    try:
        module = importlib.import_module(module_name)
    except ModuleNotFoundError as exc:
        if exc.name == module_name:
            print(f"`cassie {module_name.rsplit('.', 1)[-1]}` is not built yet", file=sys.stderr)
            return 2
        raise
    return int(module.main(rest) or 0)


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="cassie", description=__doc__)
    p.add_argument("-v", "--verbose", action="store_true", help="debug logging")
    sub = p.add_subparsers(dest="command", required=True)

    launch = sub.add_parser("launch", help="run a launch profile under the supervisor")
    launch.add_argument("profile", help="profile name or path, e.g. hw_config/sim.yaml")
    launch.add_argument("overrides", nargs="*", metavar="KEY:=VALUE",
                        help="changes to the profile: mode:=lockstep, osc.params.NAME:=V, "
                             "osc.rate_hz:=V, osc.gains.A.B:=V (tools/overrides.py)")
    launch.add_argument(
        "--duration", type=float, default=None,
        help="run for S seconds once every process is ready, print a summary and exit",
    )
    launch.add_argument("--instance", type=int, default=None, metavar="N",
                        help="this stack's instance on a shared machine: every port (LCM, UDP) "
                             "moves up by 20*N (the same as CASSIE_INSTANCE=N, which cassie "
                             "order, logs and spy read)")
    launch.add_argument("--log-dir", default=None,
                        help="folder for per-process logs (default: a new folder under "
                             "$XDG_STATE_HOME/cassie/logs, ~/.local/state/cassie/logs)")
    launch.add_argument(
        "--log",
        action="store_true",
        help="record every LCM message with lcm-logger into LOG_DIR/lcm.log",
    )
    launch.add_argument(
        "--dashboard", action="store_true", help="start the Rerun dashboard with the stack"
    )
    launch.add_argument(
        "--screen", action="store_true",
        help="every process's output on this terminal too, each line after its name (as "
             "ros2 launch's output='screen'); it still goes to its log file",
    )
    launch.add_argument(
        "--no-live",
        action="store_true",
        help="print the status table as lines instead of redrawing it",
    )

    deputy = sub.add_parser(
        "deputy", help="serve launches on this host: start, stop and watch the processes the "
        "supervisor orders for it (procman's deputy; hosts.yaml `deputy: true`)")
    deputy.add_argument("--host", required=True, help="the host of hosts.yaml this machine is")
    deputy.add_argument("--profile", default="sim",
                        help="a profile for the bus and channel names (default sim); the "
                             "orders name the profile to run")
    deputy.add_argument("--instance", type=int, default=None, metavar="N",
                        help="the instance of the launches to serve (as cassie launch's)")
    deputy.add_argument("--no-new-key", action="store_true",
                        help="fail instead of making a key when there is none (on a host the "
                             "supervisor's key file must be copied to)")

    add_run_arguments(sub.add_parser("run", help="run one process alone with a profile's "
                                     "settings"))

    # (its own options are the benchmark's: `cassie bench s3 --help` is the s3 benchmark's)
    bench = sub.add_parser("bench", help="a benchmark: " + ", ".join(BENCHMARKS),
                           add_help=False)
    bench.add_argument("name", choices=BENCHMARKS)

    sub.add_parser(
        "experiment", help="a closed-loop experiment in the deterministic harness", add_help=False
    )
    sub.add_parser("dashboard", help="the Rerun dashboard", add_help=False)
    sub.add_parser("report", help="timing report from an LCM log", add_help=False)
    sub.add_parser("command", help="send a velocity command (the radio)", add_help=False)
    sub.add_parser("log", help="record every LCM domain of a profile into one LCM log",
                   add_help=False)
    sub.add_parser("check", help="build every process of a profile (params, gains, channels) "
                   "without running it", add_help=False)
    sub.add_parser("types", help="the LCM types for Java (lcm-spy) and C++", add_help=False)
    sub.add_parser("list", help="the profiles, or one profile's processes", add_help=False)
    sub.add_parser("replay", help="feed a log to processes in the deterministic harness",
                   add_help=False)
    sub.add_parser("order", help="start, stop or restart a process of a running launch",
                   add_help=False)
    sub.add_parser("logs", help="a process's log of the running launch (-f: follow)",
                   add_help=False)
    sub.add_parser("spy", help="lcm-spy on a profile's buses, decoding every channel",
                   add_help=False)
    return p


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    # -v / --verbose anywhere on the line, not only before the subcommand (no subcommand has
    # a -v of its own)
    verbose = any(a in ("-v", "--verbose") for a in argv)
    argv = [a for a in argv if a not in ("-v", "--verbose")]
    parser = build_parser()
    if argv[:1] == ["bench"] and (len(argv) == 1 or argv[1].startswith("-")):
        print("usage: cassie bench NAME [options]; NAME one of: " + ", ".join(BENCHMARKS)
              + "\n(`cassie bench NAME --help`: that benchmark's options)")
        return 0 if argv[1:2] in (["-h"], ["--help"]) else 2
    args, rest = parser.parse_known_args(argv)
    args.verbose = args.verbose or verbose
    logging.basicConfig(
        level=logging.DEBUG if args.verbose else logging.INFO,
        format="%(asctime)s %(name)s %(levelname)s: %(message)s",
    )

    def command() -> int:
        if args.command == "bench":
            return _cmd_bench(args, rest)
        if args.command in ("list", "order", "logs"):
            from tools import control

            return int(getattr(control, f"cmd_{args.command}")(rest))
        if args.command in ("experiment", "dashboard", "report", "command", "log", "check",
                            "types", "spy", "replay"):
            module = {"log": "tools.logger", "check": "runtime.check"}.get(
                args.command, f"tools.{args.command}")
            return _cmd_module(module, rest)
        if rest:
            parser.error(f"unrecognized arguments: {' '.join(rest)}")
        if args.command == "launch":
            return _cmd_launch(args)
        if args.command == "deputy":
            return _cmd_deputy(args)
        return _cmd_run(args)

    return exit_code(command)


if __name__ == "__main__":
    sys.exit(main())
