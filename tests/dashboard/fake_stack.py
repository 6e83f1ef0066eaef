"""A fake Cassie stack for dashboard tests: realistic messages of every type, tick by tick.

One tick is 1 ms of sim time. Per tick: robot state, torque command, applied input and OSC
debug (as the 2 kHz NUC loops would, at half rate); every 5 ticks the network state and ground
truth; every 10 the MPFC plan and debug; every 33 a depth frame, an elevation map and a foothold
set carrying the frame's utime; every 100 a TIMING message per loop; every 250 the supervisor
status. All messages derived from a state carry that state's utime, as the real processes do.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from typing import Any

import numpy as np

from lcmtypes import (
    applied_input_t,
    depth_frame_t,
    elevation_map_t,
    foothold_set_t,
    ground_truth_t,
    loop_timing_t,
    mpfc_debug_t,
    mpfc_output_t,
    osc_debug_t,
    process_status_t,
    robot_state_t,
    supervisor_status_t,
    torque_command_t,
)
from runtime.codecs import MAP_OK, elevation_map_to_msg, footholds_to_msg
from runtime.geometry import Foothold

#: The menagerie Cassie's ``home`` keyframe (nq 35), so forward kinematics gives real legs.
HOME_Q = [
    0.0, 0.0, 1.00593, 1.0, 0.0, 0.0, 0.0, 0.00449956, 0.0, 0.497301, 0.978609749,
    -0.0164103958, 0.0177765954, -0.204297948, -1.1997, 0.0, 1.42671, -2.25907e-06, -1.52439,
    1.50645, -1.59681, -0.00449956, 0.0, 0.497301, 0.978739694, 0.00386869879, -0.0151571953,
    -0.204508936, -1.1997, 0.0, 1.42671, 0.0, -1.52439, 1.50645, -1.59681,
]
LOOPS = [
    ("sim", "step"), ("state_estimator", "tick"), ("osc", "tick"), ("torque_bridge", "tick"),
    ("perception", "map"), ("s3", "segment"), ("mpfc", "solve"),
]
PROCESSES = ["sim", "state_estimator", "osc", "torque_bridge", "perception", "s3", "mpfc"]
MAP_N = 40
MAP_RES = 0.05


def _header(msg: Any, utime: int, source: str) -> Any:
    msg.header.utime = utime
    msg.header.source = source
    return msg


def state(utime: int) -> robot_state_t:
    m = _header(robot_state_t(), utime, "state_estimator")
    q = list(HOME_Q)
    q[0] = 0.3 * utime * 1e-6  # walking forward at 0.3 m/s
    m.num_positions, m.num_velocities, m.num_motors = 35, 32, 10
    m.q, m.v, m.motor_torque = q, [0.0] * 32, [1.0] * 10
    m.alip_stance, m.in_contact = 0, [True, False]
    return m


def ground_truth(utime: int) -> ground_truth_t:
    s = state(utime)
    m = _header(ground_truth_t(), utime, "sim")
    m.num_positions, m.num_velocities, m.q, m.v = 35, 32, s.q, s.v
    m.foot_contact = [True, False]
    x = s.q[0]
    m.foot_pos = [[x, 0.135, 0.0], [x + 0.1, -0.135, 0.05]]
    return m


def torque(utime: int) -> torque_command_t:
    m = _header(torque_command_t(), utime, "osc")
    m.num_motors, m.torque, m.mode, m.status = 10, [0.5] * 10, 0, "walking"
    return m


def applied(utime: int) -> applied_input_t:
    m = _header(applied_input_t(), utime, "torque_bridge")
    m.num_motors, m.torque, m.commanded = 10, [0.5] * 10, [0.5] * 10
    m.status = "ok"
    return m


def osc_debug(utime: int) -> osc_debug_t:
    m = _header(osc_debug_t(), utime, "osc")
    m.tick_ms, m.solve_ms, m.qp_status, m.qp_iterations = 0.4, 0.08, 1, 7
    m.num_tasks, m.task_names, m.task_errors = 2, ["com", "swing"], [0.01, 0.02]
    return m


def plan(utime: int) -> mpfc_output_t:
    m = _header(mpfc_output_t(), utime, "mpfc")
    x = 0.3 * utime * 1e-6
    m.gait_state = (utime // 300_000) % 2  # alternate stance every 0.3 s
    m.stance = m.gait_state
    m.next_footstep_world = [x + 0.2, 0.1, 0.0]
    m.stance_foot_world = [x, -0.1, 0.0]
    m.num_footsteps = 3
    m.footsteps_world = [[x + 0.2 * (k + 1), 0.1 * (-1) ** k, 0.0] for k in range(3)]
    return m


def mpfc_debug(utime: int) -> mpfc_debug_t:
    m = _header(mpfc_debug_t(), utime, "mpfc")
    m.solve_wall_ms, m.optimizer_ms, m.nodes_explored, m.num_footholds = 2.0, 1.5, 4, 3
    m.num_steps, m.chosen_footholds = 2, [0, 1]
    m.solution_size, m.solution = 3, [0.0, 1.0, 2.0]
    return m


def depth(utime: int) -> depth_frame_t:
    m = _header(depth_frame_t(), utime, "sim")
    m.width, m.height = 32, 24
    m.fx = m.fy = 30.0
    m.cx, m.cy, m.depth_scale = 16.0, 12.0, 0.001
    m.camera_pos = [0.3 * utime * 1e-6 + 0.1, 0.0, 1.2]
    m.camera_quat = [0.5, -0.5, 0.5, -0.5]
    data = np.full(32 * 24, 1500, dtype="<u2").tobytes()
    m.num_bytes, m.data = len(data), data
    return m


def elevation_map(utime: int, with_mask: bool = False) -> elevation_map_t:
    n = MAP_N
    origin = [0.3 * utime * 1e-6 - 0.5 * (n - 1) * MAP_RES, -0.5 * (n - 1) * MAP_RES]
    jj = np.arange(n)[None, :].repeat(n, 0)
    elev = np.where(jj > n // 2, 0.15, 0.0).astype("<f4")  # a step half way
    elev[:3, :3] = np.nan
    layers = {"elevation": elev, "variance": np.full((n, n), 1e-4, "<f4")}
    if with_mask:
        mask = np.ones((n, n), "<f4")
        mask[:, n // 2 - 1 : n // 2 + 2] = 0.0  # the step edge is unsafe
        layers["s3_mask"] = mask
    m = elevation_map_to_msg(layers, MAP_RES, origin, utime, MAP_OK, "ok")
    return _header(m, utime, "perception")


def footholds(utime: int, map_seq: int) -> foothold_set_t:
    x0 = 0.3 * utime * 1e-6
    fhs = [Foothold.from_ccw(np.array([[xa, -0.9], [xb, -0.9], [xb, 0.9], [xa, 0.9]]),
                             (0.0, 0.0, 1.0), z)
           for xa, xb, z in [(x0 - 0.9, x0 - 0.05, 0.0), (x0 + 0.08, x0 + 0.9, 0.15)]]
    return _header(footholds_to_msg(fhs, utime, map_seq), utime, "s3")


def timing(utime: int, process: str, loop: str, window: int) -> loop_timing_t:
    m = _header(loop_timing_t(), utime, process)
    m.process, m.loop, m.kind = process, loop, "periodic"
    m.window_s, m.rate_hz, m.target_rate_hz, m.deadline_ms = 0.1, 2000.0, 2000.0, 0.5
    m.ticks, m.ticks_total = 200, 200 * (window + 1)
    m.deadline_misses = window % 3
    m.deadline_misses_total = sum(w % 3 for w in range(window + 1))
    m.exec_p50_ms, m.exec_p99_ms, m.exec_max_ms = 0.2, 0.4, 0.6 + 0.01 * window
    m.lateness_p50_ms, m.lateness_p99_ms, m.lateness_max_ms = 0.01, 0.05, 0.1
    m.num_samples = 4
    m.exec_ms = [0.2, 0.21, 0.3, 0.4]
    m.lateness_ms = [0.01, 0.01, 0.02, 0.05]
    m.input_age_ms = [0.1, 0.1, 0.1, 0.2]
    m.cpu_ms = [0.05, 0.05, 0.05, 0.1]
    return m


def supervisor(utime: int, k: int) -> supervisor_status_t:
    m = _header(supervisor_status_t(), 0, "supervisor")  # the supervisor has no sim time
    m.profile, m.state, m.uptime_s = "fake", "starting" if k == 0 else "running", 0.25 * k
    procs = []
    for i, name in enumerate(PROCESSES):
        p = process_status_t()
        p.name, p.host, p.required, p.pid = name, "nuc", True, 1000 + i
        p.state = "starting" if k == 0 else ("ready" if name != "s3" or k < 3 else "backoff")
        p.cpu_percent, p.rss_mb, p.loop_rate_hz = 10.0 + i, 100.0, 2000.0
        p.affinity, p.priority = "not requested", "nice 0"
        procs.append(p)
    m.num_processes, m.processes = len(procs), procs
    del utime
    return m


def messages(tick: int, with_mask: bool = False) -> Iterator[tuple[str, Any]]:
    """The messages of one 1 ms tick, in publishing order (channel, message)."""
    utime = 1_000_000 + 1000 * tick  # sim time starts at 1 s
    yield "CASSIE_STATE", state(utime)
    if tick % 5 == 0:
        yield "NETWORK_CASSIE_STATE", state(utime)
        yield "GROUND_TRUTH", ground_truth(utime)
    yield "OSC_TORQUE", torque(utime)
    yield "OSC_DEBUG", osc_debug(utime)
    yield "CASSIE_INPUT", applied(utime)
    if tick % 10 == 0:
        net_utime = utime - 1000 * (tick % 5)
        yield "NETWORK_MPFC_PLAN", plan(net_utime)
        yield "MPFC_DEBUG", mpfc_debug(net_utime)
    if tick % 33 == 0:
        yield "DEPTH", depth(utime)
        yield "ELEVATION_MAP", elevation_map(utime, with_mask)
        yield "FOOTHOLDS", footholds(utime, map_seq=tick // 33)
    if tick % 100 == 0:
        for proc, loop in LOOPS:
            yield "TIMING", timing(utime, proc, loop, tick // 100)
    if tick % 250 == 0:
        yield "SUPERVISOR_STATUS", supervisor(utime, tick // 250)


def publish_for(bus: Any, seconds: float, with_mask: bool = False) -> int:
    """Publish the fake stack on ``bus`` in real time (1 kHz ticks) for ``seconds``; returns
    the number of messages published. Late ticks are skipped, as a real-time sim would."""
    start = time.monotonic()
    n = 0
    tick = 0
    map_seq = -1
    while True:  # returns when the time is up
        now = time.monotonic()
        if now - start >= seconds:
            return n
        due = int((now - start) * 1000)
        if tick > due:
            time.sleep(max(0.0, start + tick / 1000 - now))
            continue
        for channel, msg in messages(tick, with_mask):
            if channel == "FOOTHOLDS":  # the bus numbers maps per publish; skipped ticks
                msg.map_seq = map_seq  # would break tick // 33
            bus.publish(channel, msg)
            if channel == "ELEVATION_MAP":
                map_seq = msg.header.seq
            n += 1
        tick = max(tick + 1, due)  # skip ticks we are late for


def stamp_all(batch: list[tuple[str, Any]], mono_ns: int, step_ns: int,
              seqs: dict[str, int]) -> dict[str, list[bytes]]:
    """Encode ``(channel, message)`` pairs as a bus would, without one: per-channel ``seq``
    and send times ``mono_ns``, ``mono_ns + step_ns``, ... (for deterministic latencies)."""
    out: dict[str, list[bytes]] = {}
    for k, (channel, msg) in enumerate(batch):
        msg.header.seq = seqs.get(channel, 0)
        seqs[channel] = msg.header.seq + 1
        msg.header.send_mono_ns = mono_ns + k * step_ns
        out.setdefault(channel, []).append(msg.encode())
    return out
