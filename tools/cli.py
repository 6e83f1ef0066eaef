"""The ``cassie`` command: launch a profile, run one process, benchmarks, experiments, tools."""

from __future__ import annotations

import argparse
import importlib
import logging
import os
import sys
import time
from pathlib import Path
from typing import Any

from runtime.errors import BusError, ConfigError, MulticastRouteError

BENCHMARKS = ("sim", "estimator", "mpfc", "osc", "s3", "lcm", "launch", "bridge")


def _cmd_launch(args: argparse.Namespace) -> int:
    from runtime.config import find_profile, load_profile
    from runtime.supervisor import Supervisor, new_log_dir

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
    sup = Supervisor(
        profile,
        log_dir=log_dir,
        duration_s=args.duration,
        live_table=False if args.no_live else None,
        log_lcm=args.log,
        dashboard=args.dashboard,
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
    from runtime.builder import build_node, process_module
    from runtime.config import load_profile
    from runtime.loops import LiveRunner
    from runtime.scheduling import apply_scheduling, pin_to_supervisor_host

    profile = load_profile(args.profile)
    if args.process not in profile.processes:
        raise ConfigError(
            str(profile.path),
            "processes",
            f"no process named {args.process!r}",
            allowed=", ".join(sorted(profile.processes)),
        )
    proc = profile.processes[args.process]
    log = logging.getLogger(proc.name)
    # nice and affinity now, before any thread or child exists; the real-time priority once
    # the node is set up (runtime.loops.LiveRunner.run)
    for note in apply_scheduling(proc):
        (log.warning if "failed" in note else log.info)(note)
    if args.standby:  # a spare: set up at the lowest priority, then wait (see _standby)
        os.setpriority(os.PRIO_PROCESS, 0, 19)
        # ... and away from its host's CPUs: a minute of numba loading and warm-up beside the
        # NUC's loops, even at nice 19, took 16 % of their CPU and its caches (perf sched,
        # measured), and their deadlines with it. It moves home once it is set up.
        pin_to_supervisor_host(profile)
    module = process_module(proc)
    if hasattr(module, "make_node"):
        node = build_node(proc, profile)
        set_up = False
        succession = None
        if args.standby:
            took_over, succession = _standby(node, proc, log)
            if not took_over:
                return 0
            set_up = True
        domains = sorted({profile.channel_domains.get(c.name, "network")
                          for c in (*proc.inputs.values(), *proc.outputs.values()) if not c.is_udp})
        log.info(
            "%s: running %s (%s) on host %s; LCM domains %s",
            proc.name,
            type(node).__name__,
            proc.module,
            proc.host,
            ", ".join(f"{d} ({profile.domains.get(d, profile.lcm_url)})" for d in domains),
        )
        runner = LiveRunner(node, proc, profile)
        if prof_dir := os.environ.get(CPROFILE_ENV):
            return _profiled(runner, Path(prof_dir) / f"{proc.name}.prof", args.duration, set_up,
                             succession)
        return runner.run(duration_s=args.duration, set_up=set_up, succession=succession)
    if hasattr(module, "main"):
        _started(proc, profile)
        return int(module.main(proc, profile) or 0)
    raise ConfigError(
        str(proc.source_file),
        proc.key("module"),
        f"module {proc.module} defines neither make_node(proc, profile) nor main(proc, profile)",
    )


#: set to a folder, ``cassie run`` profiles its loop with cProfile and writes
#: ``<folder>/<process>.prof`` when it stops (a launch passes it on to every process): where a
#: live loop's CPU goes, ticks and runtime glue alike (cProfile roughly doubles the cost of
#: Python calls: compare call counts and shares, not absolute times)
CPROFILE_ENV = "CASSIE_CPROFILE_DIR"


def _profiled(runner: Any, out: Path, duration: float | None, set_up: bool,
              succession: Any = None) -> int:
    """``runner.run`` under cProfile, the statistics written to ``out`` (pstats format)."""
    import cProfile

    prof = cProfile.Profile()
    prof.enable()
    try:
        return runner.run(duration_s=duration, set_up=set_up, succession=succession)
    finally:
        prof.disable()
        out.parent.mkdir(parents=True, exist_ok=True)
        prof.dump_stats(str(out))


class _SetUpOnly:
    """The context a standby's node is set up with: nothing may be sent yet."""

    now_utime = 0

    def publish(self, role: str, msg: object) -> None:
        raise RuntimeError(f"this node publishes {role!r} during its set-up: it cannot wait as "
                           "a standby (set restart.standby: false for it)")

    def due(self, role: str) -> bool:
        return False


def _standby(node: object, proc: Any, log: logging.Logger) -> tuple[bool, Any]:
    """A spare copy of a process (``restart.standby``): set up and warmed up like the real
    one, but bound to no port and subscribed to nothing, until its process dies. It learns
    that from the process's succession lock (``runtime.succession``: the moment the kernel
    starts to end the process) or from the supervisor's ``go`` on stdin, whichever comes
    first; then it takes the process's own priority and runs. Returns (take over?, the
    succession lock it holds, if any); (False, None) when stdin closes (the launch is over)."""
    import select

    from runtime.loops import settle
    from runtime.scheduling import apply_scheduling, rt_priority
    from runtime.succession import Succession

    t0 = time.monotonic()
    node.setup(_SetUpOnly())  # type: ignore[attr-defined]
    node.warm_up()  # type: ignore[attr-defined]
    settle(proc)
    log.info("standby: set up in %.1f s, waiting for its process to end", time.monotonic() - t0)
    if aff := getattr(proc, "cpu_affinity", None):  # home to its host's CPUs (it only waits)
        try:
            os.sched_setaffinity(0, aff)
        except OSError as exc:
            log.warning("standby: cpu affinity %s: failed (%s)", list(aff), exc.strerror)
    from runtime.supervisor import STANDBY_FD_ENV

    succession = Succession.for_process(proc.name)
    wake_r = -1
    if succession is not None and (prio := getattr(proc, "rt_priority", None)) is not None:
        # wait one step above the process's own real-time priority (waiting costs no CPU):
        # a killed process's kernel teardown runs at its priority on its CPU, 10-30 ms for
        # ~550 MB locked, and at nice 19 the standby woke only after it (measured: 14 ms from
        # the kill to the first torque, past the target PC's 10 ms watchdog)
        for note in rt_priority(min(int(prio) + 1, 99)):
            if "failed" in note:
                log.warning("standby: %s", note)
    elif succession is not None and getattr(proc, "nice", None) is not None:
        # ... and a process of the normal scheduler at its own nice: the OSC's standby, woken
        # at nice 19 beside the dying OSC's teardown at nice -20, ran 64.7 ms after the kill
        # (perf sched), the bridge's watchdog damping all the while
        try:
            os.setpriority(os.PRIO_PROCESS, 0, int(proc.nice))
        except OSError as exc:
            log.warning("standby: nice %s: failed (%s)", proc.nice, exc.strerror)
    if succession is not None:
        wake_r, wake_w = os.pipe()
        succession.watch(wake_w)
    if (fd := os.environ.get(STANDBY_FD_ENV)) is not None:
        try:
            os.write(int(fd), b"ready\n")
            os.close(int(fd))
        except (OSError, ValueError):
            pass  # no supervisor listening: it learns nothing, the standby still waits
    how = ""
    while not how:
        waits = [sys.stdin] + ([wake_r] if wake_r >= 0 else [])
        ready, _, _ = select.select(waits, [], [])
        if wake_r in ready:
            os.read(wake_r, 1)
            assert succession is not None
            if succession.crashed.is_set():
                how = "its process died (succession lock), before the supervisor's go"
            else:  # it ended in order: no take-over unless the supervisor says go
                os.close(wake_r)
                wake_r, succession = -1, None
        if sys.stdin in ready:
            line = sys.stdin.readline()
            if line.strip() != "go":
                return False, None
            how = "the supervisor's go"
    # real-time priority at once: what is left before the first packet must not wait behind
    # the host's other loops (the runner applies it again, with the rest of its scheduling)
    os.setpriority(os.PRIO_PROCESS, 0, getattr(proc, "nice", None) or 0)
    for note in apply_scheduling(proc, realtime=True):
        if "failed" in note:
            log.warning(note)
    log.info("standby: taking over on %s", how)
    if succession is not None and not succession.crashed.is_set():
        # go before the lock came: the kernel releases it before the exit shows, so it is due
        for _ in range(100):
            if succession.crashed.is_set() or succession.ended.is_set():
                break
            time.sleep(0.01)
        if succession.ended.is_set():
            succession = None  # given back in order: the runner takes it itself
        elif not succession.crashed.is_set():
            log.warning("standby: told to go while %s is still held: its lock will be this "
                        "copy's once the other copy ends", succession.path)
    return True, succession


def _started(proc: object, profile: object) -> None:
    """One TIMING message for a process that is not a Node (``main(proc, profile)``): the
    supervisor's sign that it started, as a node's runner sends after its setup."""
    from lcmtypes import loop_timing_t
    from runtime.bus import Bus
    from runtime.pairing import publish_timing, timing_key

    msg = loop_timing_t()
    msg.process = msg.loop = msg.header.source = proc.name  # type: ignore[attr-defined]
    msg.kind = "main"
    msg.status = "started"
    bus = Bus.for_profile(profile, source=proc.name)  # type: ignore[arg-type]
    publish_timing(bus, profile.timing_channel, msg, timing_key())  # type: ignore[attr-defined]
    bus.close()


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

    run = sub.add_parser("run", help="run one process alone with a profile's settings")
    run.add_argument("process")
    run.add_argument("--profile", required=True)
    run.add_argument("--duration", type=float, default=None)
    run.add_argument("--standby", action="store_true",
                     help="set up, then wait for `go` on stdin before running (the "
                          "supervisor's spare for restart.standby)")

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
    try:
        if args.command == "bench":
            return _cmd_bench(args, rest)
        if args.command in ("list", "order", "logs"):
            from tools import control

            return int(getattr(control, f"cmd_{args.command}")(rest))
        if args.command in ("experiment", "dashboard", "report", "command", "log", "check",
                            "types", "spy", "replay"):
            module = {"log": "logger"}.get(args.command, args.command)
            return _cmd_module(f"tools.{module}", rest)
        if rest:
            parser.error(f"unrecognized arguments: {' '.join(rest)}")
        if args.command == "launch":
            return _cmd_launch(args)
        if args.command == "deputy":
            return _cmd_deputy(args)
        return _cmd_run(args)
    except ConfigError as exc:
        print(f"config error: {exc}", file=sys.stderr)
        return 2
    except MulticastRouteError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 3
    except BusError as exc:
        print(f"bus error: {exc}", file=sys.stderr)
        return 3
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    sys.exit(main())
