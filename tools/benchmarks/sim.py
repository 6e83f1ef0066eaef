"""`cassie bench sim`: the MuJoCo target PC alone at wall-clock 2 kHz, with real UDP packets.

This process runs the sim's real-time loop as the live runner does (absolute deadlines
``t0 + k * 0.5 ms``, sleep then spin, missed slots skipped and counted as overruns): each tick
takes the newest torque packet from its socket, steps the physics once (``mj_step`` in place),
and sends the state packet. A peer *process* stands in for the NUC: it decodes every state and
answers with a torque packet (zero torques, so the start-up holder keeps the robot standing).
The depth camera renders at 30 Hz in its child process, as in the sim process, and its
frame time is measured both there and alone. `step_cpu` is the loop thread's own CPU time per
tick (the work, without preemption by other processes), `step` its wall time.
"""

from __future__ import annotations

import argparse
import gc
import os
import signal
import socket
import subprocess
import sys
import time

import numpy as np

from tools.benchmarks.common import print_table, summarize, write_json

PERIOD_S = 0.0005


def _peer(sim_port: int) -> int:
    """The NUC stand-in: answer each state packet with a zero-torque packet."""
    from runtime.cassie_packets import InputPacket, LinkCounter, OutputPacket, PacketError

    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    sock.connect(("127.0.0.1", sim_port))
    sock.settimeout(5.0)
    print(sock.getsockname()[1], flush=True)
    state, cmd, link = OutputPacket(), InputPacket(), LinkCounter()
    buf = bytearray(2048)
    view = memoryview(buf)
    stop = False

    def on_sig(*_: object) -> None:
        nonlocal stop
        stop = True

    signal.signal(signal.SIGTERM, on_sig)
    while not stop:
        try:
            n = sock.recv_into(buf)
        except (TimeoutError, InterruptedError):
            break
        except ConnectionRefusedError:
            continue
        try:
            state.decode(view[:n])
        except PacketError:
            link.on_error()
            continue
        link.on_receive(state.seq, state.ack)
        try:
            sock.send(cmd.encode(link.next_seq(), link.last_peer_seq))
        except ConnectionRefusedError:
            pass
    print(f"peer: {link.summary()}", file=sys.stderr, flush=True)
    return 0


def _spin_until(deadline_ns: int, spin_ns: int) -> None:
    rest = deadline_ns - time.monotonic_ns() - spin_ns
    if rest > 0:
        time.sleep(rest / 1e9)
    while time.monotonic_ns() < deadline_ns:
        pass


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="cassie bench sim", description=__doc__.split("\n")[0])
    ap.add_argument("--json", metavar="FILE", help="write the figures as one flat JSON object")
    ap.add_argument("--seconds", type=float, default=10.0, help="length of the 2 kHz run")
    ap.add_argument("--terrain", default="stairs", help="terrain generator (default: stairs)")
    ap.add_argument("--no-camera", action="store_true", help="run without the depth renderer")
    ap.add_argument("--spin-us", type=float, default=150.0, help="spin before each deadline")
    ap.add_argument("--peer", type=int, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.peer is not None:
        return _peer(args.peer)

    os.environ.setdefault("MENAGERIE_ROOT", "/work/shared/menagerie")
    from sim.camera import CameraConfig, DepthCamera, ProcessDepthRenderer
    from sim.target_pc import SimConfig, TargetPC, make_core
    from sim.terrain import generate

    load_before = os.getloadavg()[0]
    terrain = generate(args.terrain)
    sim_cfg = SimConfig()
    tpc = TargetPC(make_core(terrain, sim_cfg), "realtime")
    core = tpc.core

    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    sock.setblocking(False)
    peer = subprocess.Popen(
        [sys.executable, "-m", "tools.benchmarks.sim", "--peer", str(sock.getsockname()[1])],
        stdout=subprocess.PIPE, text=True,
    )
    try:
        assert peer.stdout is not None
        sock.connect(("127.0.0.1", int(peer.stdout.readline())))

        # depth: alone first (the frame time with nothing else running in this process)
        cam_cfg = CameraConfig()
        cam = DepthCamera(core.m, cam_cfg)
        alone = []
        for _ in range(30):
            t = time.perf_counter()
            cam.render(core.d.qpos)
            alone.append(time.perf_counter() - t)
        renderer = None
        if not args.no_camera:
            h = sim_cfg.holder
            renderer = ProcessDepthRenderer((terrain, sim_cfg.impratio,
                                             (h.timeconst_s, h.dampratio)), cam_cfg)
            renderer.wait_ready()

        n_max = int(args.seconds / PERIOD_S) + 10
        step = np.zeros(n_max)
        cpu = np.zeros(n_max)  # this thread's CPU time per tick: the work, without preemption
        late = np.zeros(n_max)
        rx_bufs = (bytearray(2048), bytearray(2048))
        rx_views = (memoryview(rx_bufs[0]), memoryview(rx_bufs[1]))
        period_ns = int(PERIOD_S * 1e9)
        spin_ns = int(args.spin_us * 1e3)
        depth_every = round(1.0 / cam_cfg.rate_hz / PERIOD_S)
        render_times: list[float] = []
        gc.collect()
        gc.freeze()
        gc.disable()
        t0 = time.monotonic_ns()
        end_ns = t0 + int(args.seconds * 1e9)
        sim0 = core.time
        k = 0
        i = 0
        overruns = 0
        while True:
            scheduled = t0 + k * period_ns
            _spin_until(scheduled, spin_ns)
            start = time.monotonic_ns()
            cpu0 = time.thread_time_ns()
            got = 0
            cur = 0
            while True:  # apply the newest datagram; account the ones it supersedes
                try:
                    n = sock.recv_into(rx_bufs[cur])
                except (BlockingIOError, InterruptedError):
                    break
                if got:
                    tpc.receive(rx_views[1 - cur][:got])
                got = n
                cur = 1 - cur
            out = tpc.realtime_cycle(rx_views[1 - cur][:got] if got else None)
            try:
                sock.send(out)
            except ConnectionRefusedError:
                pass
            if renderer is not None and core.steps % depth_every == 0:
                frame = renderer.poll()
                if frame is not None:
                    render_times.append(frame.render_s)
                renderer.request(core.d.qpos, core.utime)
            cpu[i] = (time.thread_time_ns() - cpu0) / 1e6
            end = time.monotonic_ns()
            step[i] = (end - start) / 1e6
            late[i] = (start - scheduled) / 1e6
            tpc.stats.record((end - start) / 1e9, core.time, 0)
            i += 1
            k += 1
            if end > t0 + k * period_ns:  # missed the next slot: skip, never catch up in bursts
                k_new = (end - t0) // period_ns + 1
                overruns += k_new - k
                k = k_new
            if end >= end_ns:
                break
        wall = (time.monotonic_ns() - t0) / 1e9
        gc.enable()
        sim_elapsed = core.time - sim0
        dropped = 0
        if renderer is not None:
            time.sleep(0.1)
            frame = renderer.poll()
            if frame is not None:
                render_times.append(frame.render_s)
            dropped = renderer.dropped
            renderer.close()
    finally:
        peer.send_signal(signal.SIGTERM)
        try:
            peer.wait(timeout=5.0)
        except subprocess.TimeoutExpired:
            peer.kill()
        sock.close()

    step = step[:i]
    cpu = cpu[:i]
    late = late[:i]
    figures: dict[str, object] = {
        "terrain": args.terrain,
        "camera_process": renderer is not None,
        "duration_s": wall,
        "ticks": i,
        "slots": k,
    }
    figures.update(summarize(step, "step"))
    figures.update(summarize(cpu, "step_cpu"))
    figures.update(summarize(late, "start_late"))
    figures.update({
        "step_over_period_fraction": float((step > PERIOD_S * 1e3).mean()),
        "overruns": overruns,
        "overrun_fraction": overruns / max(k, 1),
        "realtime_factor": sim_elapsed / wall,
        "packets_sent": tpc.link.sent,
        "packets_received": tpc.link.received,
        "packets_lost_by_peer": tpc.link.lost,
        "round_trip_max_cycles": tpc.link.max_round_trip_cycles,
        "malformed": tpc.link.malformed,
        "depth_size": f"{cam_cfg.out_width}x{cam_cfg.out_height}",
        "load_avg_1min_before": load_before,
        "load_avg_1min_after": os.getloadavg()[0],
    })
    figures.update(summarize(np.array(alone) * 1e3, "depth_alone"))
    if render_times:
        figures.update(summarize(np.array(render_times) * 1e3, "depth_in_loop"))
        figures["depth_frames_dropped"] = dropped
    print_table("sim: target PC alone at 2 kHz (mj_step + UDP packet I/O)", figures)
    write_json(args.json, "sim", figures)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
