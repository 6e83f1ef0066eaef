"""``cassie dashboard``: stream the LCM bus to Rerun, live or headless (``--save FILE.rrd``).

A separate, niced process: an LCM thread files raw messages into bounded per-channel buffers
(dropping and counting its own oldest messages when full), and the main thread converts each
batch to columns and sends them with ``rr.send_columns`` at most 30 times a second. Nothing is
ever published on the bus, so no control loop can be slowed down by it.
"""

from __future__ import annotations

import argparse
import logging
import os
import signal
import sys
import threading
import time
from types import FrameType
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import rerun as rr
    import rerun.blueprint as rrb

log = logging.getLogger("dashboard")

MAX_RATE_HZ = 30.0
HEADLESS_RATE_HZ = 10.0  # same content, a third of the per-send overhead
FLUSH_TIMEOUT_S = 5.0


def build_parser() -> argparse.ArgumentParser:
    """The options of ``cassie dashboard`` (docs/dashboard.md explains them)."""
    p = argparse.ArgumentParser(
        prog="cassie dashboard",
        description="Stream the LCM bus to Rerun: timing, latencies, states, robot and maps.",
    )
    p.add_argument("--save", metavar="FILE.rrd", help="run headless and write a recording")
    p.add_argument(
        "--profile",
        default=None,
        help="launch profile for channel names and LCM URL "
        "(default: hw_config/sim.yaml if it exists, else hw_config channels/hosts)",
    )
    p.add_argument("--duration", type=float, default=None, metavar="S", help="stop after S s")
    p.add_argument(
        "--connect", metavar="URL", default=None,
        help="stream to a running viewer (e.g. rerun+http://127.0.0.1:9876/proxy)",
    )
    p.add_argument("--spawn", action="store_true", help="spawn a Rerun viewer and stream to it")
    p.add_argument(
        "--viewer-memory", default="25%",
        help="memory limit of a spawned viewer; it drops its oldest data beyond (default 25%%)",
    )
    p.add_argument(
        "--rate", type=float, default=None, metavar="HZ",
        help=f"batches per second, at most {MAX_RATE_HZ:g} (default: {MAX_RATE_HZ:g} live, "
        f"{HEADLESS_RATE_HZ:g} headless, where a batch's size does not matter)",
    )
    p.add_argument("--robot-hz", type=float, default=30.0, help="robot poses per sim second")
    p.add_argument("--map-hz", type=float, default=10.0, help="elevation maps drawn per second")
    p.add_argument(
        "--buffer-scale", type=float, default=1.0,
        help="multiply every per-channel buffer size (see tools/dashboard/channels.py)",
    )
    p.add_argument("--terrain", default=None, help="terrain to draw (name or YAML file)")
    p.add_argument("--no-skeleton", action="store_true",
                   help="skip the MuJoCo model (pelvis pose and feet only)")
    p.add_argument("--no-meshes", action="store_true",
                   help="draw the legs as a stick skeleton instead of the model's meshes")
    p.add_argument("--nice", type=int, default=10, help="niceness increment (default 10)")
    return p


class _Stop:
    """Set by SIGINT/SIGTERM so that the recording is flushed and closed cleanly."""

    def __init__(self) -> None:
        self.event = threading.Event()

    def __call__(self, signum: int, _frame: FrameType | None) -> None:
        self.event.set()


def _put_rerun_on_path() -> None:
    """The viewer is the ``rerun`` script next to this Python (a venv that is not activated
    has it off PATH); spawning looks for it on PATH."""
    import shutil

    here = os.path.dirname(sys.executable)
    if shutil.which("rerun") is None and os.path.exists(os.path.join(here, "rerun")):
        os.environ["PATH"] = here + os.pathsep + os.environ.get("PATH", "")


def _open_recording(args: argparse.Namespace, blueprint: rrb.Blueprint) -> rr.RecordingStream:
    """A RecordingStream with the sinks the arguments ask for (default: spawn a viewer)."""
    import rerun as rr

    rec = rr.RecordingStream("cassie_dashboard")
    if args.save:
        os.makedirs(os.path.dirname(os.path.abspath(args.save)), exist_ok=True)
    live = args.spawn or args.connect or not args.save
    if args.save and not live:
        rec.save(args.save, default_blueprint=blueprint)
        return rec
    sinks: list[rr.GrpcSink | rr.FileSink] = []
    if args.spawn or not args.connect:
        _put_rerun_on_path()
        rec.spawn(connect=False, memory_limit=args.viewer_memory)  # the viewer process only
    sinks.append(rr.GrpcSink(args.connect) if args.connect else rr.GrpcSink())
    if args.save:
        sinks.append(rr.FileSink(args.save))
    rec.set_sinks(*sinks, default_blueprint=blueprint)
    return rec


def main(argv: list[str] | None = None) -> int:
    """Run the dashboard until ``--duration`` elapses or SIGINT/SIGTERM; returns the exit code."""
    args = build_parser().parse_args(argv)
    if not logging.getLogger().handlers:
        logging.basicConfig(
            level=logging.INFO, format="%(asctime)s %(name)s %(levelname)s: %(message)s"
        )
    headless = bool(args.save) and not (args.spawn or args.connect)
    if args.rate is None:
        args.rate = HEADLESS_RATE_HZ if headless else MAX_RATE_HZ
    for flag in ("rate", "robot_hz", "map_hz", "buffer_scale"):
        if not getattr(args, flag) > 0:
            print(f"--{flag.replace('_', '-')} must be > 0", file=sys.stderr)
            return 2
    try:
        os.nice(max(0, args.nice))
    except OSError as exc:
        log.warning("could not renice (%s)", exc)

    from tools.dashboard.blueprint import build_blueprint, log_static
    from tools.dashboard.channels import resolve_setup
    from tools.dashboard.collector import Collector
    from tools.dashboard.convert import Batcher
    from tools.dashboard.robot import load_skeleton, log_meshes
    from tools.dashboard.terrain import find_terrain, log_terrain

    setup = resolve_setup(args.profile)
    stop = _Stop()
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, stop)
        signal.signal(signal.SIGTERM, stop)

    prof = setup.profile
    collector = Collector(
        setup.lcm_url,
        setup.channels.capacities(args.buffer_scale),
        keep_bytes=setup.channels.keep_bytes(),
        domains=prof.domains if prof is not None else None,
        channel_domains=prof.channel_domains if prof is not None else None,
    )
    collector.start()  # listen first: the model and viewer set-up below take a second or two
    # (the model before the layout: whether the meshes loaded decides what the 3D view shows)
    skeleton = None if args.no_skeleton else load_skeleton(meshes=not args.no_meshes)
    meshes = skeleton is not None and skeleton.has_meshes
    try:
        loops = ([(n, n, prof.processes[n].deadline_ms) for n in prof.launch]
                 if prof is not None else None)
        rec = _open_recording(args, build_blueprint(loops=loops, robot_meshes=meshes))
    except (RuntimeError, OSError) as exc:
        collector.stop()
        print(f"dashboard: cannot open the Rerun output: {exc}", file=sys.stderr)
        return 3
    log_static(rec)
    terrain = find_terrain(setup.profile, args.terrain)
    if terrain is not None:
        log_terrain(rec, terrain)
    if meshes and skeleton is not None:
        log_meshes(rec, skeleton)  # once, static: per frame only the body poses are sent
    batcher = Batcher(
        rec,
        setup.channels,
        skeleton=skeleton,
        robot_hz=args.robot_hz,
        map_hz=args.map_hz,
    )
    where = args.save if headless else "the viewer"
    print(f"dashboard: listening on {setup.lcm_url}, streaming to {where}", flush=True)

    code = 0
    period = 1.0 / min(args.rate, MAX_RATE_HZ)
    end = None if args.duration is None else time.monotonic() + args.duration
    next_t = time.monotonic()
    try:
        while not stop.event.is_set():
            now = time.monotonic()
            if end is not None and now >= end:
                break
            if next_t > now:
                stop.event.wait(next_t - now)
                continue
            batcher.process(collector.take(), collector.stats)
            # fixed rate, but never catch up: a slow batch just delays the next one
            next_t = max(next_t + period, time.monotonic())
    finally:
        collector.stop()
        batcher.process(collector.take(), collector.stats, flush=True)
        try:
            # bounded: with no viewer listening, an unbounded flush would never return
            rec.flush(timeout_sec=FLUSH_TIMEOUT_S)
            rec.disconnect()
        except RuntimeError as exc:  # the viewer went away: nothing more to deliver
            print(f"dashboard: could not deliver the last data: {exc}", file=sys.stderr)
            code = 1
        received, dropped = collector.totals()
        rejected = ", ".join(f"{ch} {n}" for ch, n in batcher.rejected.items()) or "none"
        print(
            f"dashboard: {batcher.batches} batches, {received} messages received, "
            f"{dropped} dropped from full buffers; rejected (not the expected type): {rejected}",
            flush=True,
        )
    return code
