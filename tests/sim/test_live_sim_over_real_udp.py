"""The sim node under the runtime's live runner with real UDP sockets and a peer thread that
answers each state: in real time (2 kHz wall clock, depth frames from the render process, the
watchdog zeroing torque once the peer goes quiet) and in lockstep (one step per answer, then
reported timeouts and resent states once the peer goes quiet)."""

from __future__ import annotations

import socket
import threading
from pathlib import Path

import numpy as np

from runtime.builder import build_node
from runtime.cassie_packets import (
    STATUS_HOLDER_ENGAGED,
    STATUS_LOCKSTEP,
    STATUS_WATCHDOG_TRIPPED,
    InputPacket,
    LinkCounter,
    OutputPacket,
)
from runtime.config_types import ChannelConfig, ProcessConfig, Profile
from runtime.loops import LiveRunner
from sim.process import SimNode

from .conftest import HW_CONFIG


def _free_port() -> int:
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


class Peer:
    """A NUC stand-in on a real socket: decodes every state, answers while ``answering``."""

    def __init__(self, out_port: int, in_port: int) -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", out_port))
        self.sock.settimeout(0.2)
        self.in_port = in_port
        self.answering = threading.Event()
        self.answering.set()
        self.done = threading.Event()
        self.seen: list[tuple[int, int, int]] = []  # (status, seq, utime) of every state
        self.link = LinkCounter()
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self) -> None:
        state, cmd = OutputPacket(), InputPacket()
        cmd.torque[:] = 1.0  # non-zero: the controller "takes over", the holder lets go
        while not self.done.is_set():
            try:
                data = self.sock.recv(2048)
            except TimeoutError:
                continue
            state.decode(data)
            self.link.on_receive(state.seq, state.ack)
            self.seen.append((state.status, state.seq, state.utime))
            if self.answering.is_set():
                self.sock.sendto(cmd.encode(self.link.next_seq(), self.link.last_peer_seq),
                                 ("127.0.0.1", self.in_port))

    def stop(self) -> None:
        self.done.set()
        self.thread.join(2.0)
        self.sock.close()


def _setup(mode: str, lcm_url: str, gains: Path) -> tuple[SimNode, ProcessConfig, Profile, Peer]:
    out_port, in_port = _free_port(), _free_port()
    chans = {
        "robot_output": ChannelConfig("robot_output", f"udp:127.0.0.1:{out_port}",
                                      ("127.0.0.1", out_port)),
        "robot_input": ChannelConfig("robot_input", f"udp:127.0.0.1:{in_port}",
                                     ("127.0.0.1", in_port)),
        "ground_truth": ChannelConfig("ground_truth", "GROUND_TRUTH_TEST"),
        "depth": ChannelConfig("depth", "DEPTH_TEST"),
    }
    proc = ProcessConfig(
        name="sim", host="target", module="sim.process", source_file=HW_CONFIG / "test.yaml",
        rate_hz=2000.0, inputs={"command": chans["robot_input"]},
        outputs={"robot_output": chans["robot_output"], "ground_truth": chans["ground_truth"],
                 "depth": chans["depth"]},
        params={"terrain": "flat"}, gains_file=gains)
    profile = Profile(name="live-test", path=HW_CONFIG / "test.yaml", hw_config_dir=HW_CONFIG,
                      mode=mode, lcm_url=lcm_url, hosts={}, channels=chans,  # type: ignore[arg-type]
                      processes={"sim": proc}, launch=("sim",))
    node = build_node(proc, profile)
    assert isinstance(node, SimNode)
    return node, proc, profile, Peer(out_port, in_port)


def _run(node: SimNode, proc: ProcessConfig, profile: Profile, peer: Peer, quiet_at: float,
         stop_at: float) -> None:
    runner = LiveRunner(node, proc, profile)
    timers = [threading.Timer(quiet_at, peer.answering.clear), threading.Timer(stop_at,
                                                                               runner.stop)]
    for t in timers:
        t.start()
    try:
        runner.run()
    finally:
        for t in timers:
            t.cancel()
        peer.stop()


def test_live_realtime_sim_answers_a_udp_peer_and_its_watchdog_trips_when_the_peer_stops(
        lcm_url: str) -> None:
    node, proc, profile, peer = _setup("realtime", lcm_url, HW_CONFIG / "gains" / "sim.yaml")
    assert node.renderer is not None and node.renderer.wait_ready(60.0)  # slow on a busy box
    _run(node, proc, profile, peer, quiet_at=3.0, stop_at=4.0)
    assert node.tpc.link.received > 200 and node.tpc.link.malformed == 0
    assert peer.link.received > 400 and peer.link.malformed == 0
    assert not node.core.holder_engaged
    statuses = np.array([s for s, _, _ in peer.seen])
    tripped = (statuses & STATUS_WATCHDOG_TRIPPED) != 0
    assert tripped[0] and not tripped[len(tripped) // 3]  # zero until commands came, then live
    assert tripped[-1]  # the peer went quiet: zero torque after 10 ms of sim time
    assert statuses[0] & STATUS_HOLDER_ENGAGED and not statuses[-1] & STATUS_HOLDER_ENGAGED
    assert node.depth_published > 0  # frames from the render process reached LCM


def test_live_lockstep_sim_steps_once_per_answer_and_reports_timeouts(
        lcm_url: str, tmp_path: Path) -> None:
    gains = tmp_path / "sim.yaml"
    gains.write_text("lockstep: {timeout_s: 0.05}\ncamera: {enabled: false}\n")
    node, proc, profile, peer = _setup("lockstep", lcm_url, gains)
    assert node.trigger_role == "command" and node.trigger_timeout_s == 0.05
    _run(node, proc, profile, peer, quiet_at=1.5, stop_at=2.0)
    utimes = [u for _, _, u in peer.seen]
    steps = node.core.steps
    assert steps > 100 and node.tpc.unanswered == 0
    # every step answered exactly one state: states advance by one physics step each
    assert sorted(set(utimes)) == [500 * k for k in range(steps + 1)]
    assert all(s & STATUS_LOCKSTEP for s, _, _ in peer.seen)
    # the peer went quiet: the sim stopped stepping, reported timeouts, resent the last state
    assert node.tpc.timeouts >= 3 and utimes[-1] == utimes[-2] == 500 * steps
    assert peer.link.duplicates >= 3 and "timeouts=" in node.status()
