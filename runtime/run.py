"""Running one process of a profile: the entry point the supervisor (and a deputy) starts,
``python -m runtime.run NAME --profile PROFILE [--standby]`` (``cassie run`` is the same).

The node is built by ``runtime.builder`` and run by ``runtime.loops.LiveRunner``; a spare
(``--standby``) is set up, then waits for its process to end (``wait_as_standby``). A module
that runs no node (``main(proc, profile)``) is started with one TIMING message as its sign.
"""

from __future__ import annotations

import argparse
import logging
import os
import sys
import time
from pathlib import Path
from typing import Any

from runtime.errors import ConfigError, exit_code


def run_process(args: argparse.Namespace) -> int:
    """``args.process`` of ``args.profile``, live, until stopped (or ``args.duration``)."""
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
    if args.standby:  # a spare: set up at the lowest priority, then wait (see wait_as_standby)
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
            took_over, succession = wait_as_standby(node, proc, log)
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


def wait_as_standby(node: object, proc: Any, log: logging.Logger) -> tuple[bool, Any]:
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


def add_arguments(p: argparse.ArgumentParser) -> argparse.ArgumentParser:
    """The arguments of one process's run (``python -m runtime.run`` and ``cassie run``)."""
    p.add_argument("process")
    p.add_argument("--profile", required=True)
    p.add_argument("--duration", type=float, default=None)
    p.add_argument("--standby", action="store_true",
                   help="set up, then wait for `go` on stdin before running (the "
                        "supervisor's spare for restart.standby)")
    return p


def parser() -> argparse.ArgumentParser:
    return add_arguments(argparse.ArgumentParser(prog="python -m runtime.run",
                                                 description=__doc__.split("\n")[0]))


def main(argv: list[str] | None = None) -> int:
    args = parser().parse_args(argv)
    logging.basicConfig(level=logging.DEBUG if os.environ.get("CASSIE_VERBOSE") else logging.INFO,
                        format="%(asctime)s %(name)s %(levelname)s: %(message)s")
    return exit_code(lambda: run_process(args))


if __name__ == "__main__":
    sys.exit(main())
