"""Typed, validated views of hw_config: what the loader in ``runtime.config`` returns."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

Mode = Literal["realtime", "lockstep"]
RestartKind = Literal["always", "on-failure", "never"]


@dataclass(frozen=True)
class ChannelConfig:
    """One named link: an LCM channel, or a UDP address the receiver binds and senders target."""

    key: str
    name: str  # LCM channel name, or "udp:HOST:PORT" for a UDP link
    udp: tuple[str, int] | None = None

    @property
    def is_udp(self) -> bool:
        return self.udp is not None

    @property
    def ttl(self) -> int:
        """LCM ttl: 1 for channels that cross NUC <-> laptop (``NETWORK_`` prefix), else 0."""
        return 1 if self.name.startswith("NETWORK_") else 0


@dataclass(frozen=True)
class RestartPolicy:
    """When and how fast the supervisor restarts a process, and when it gives up."""

    policy: RestartKind = "on-failure"
    max_restarts: int = 5  # within window_s; one more and the process is in crash_loop
    window_s: float = 60.0
    backoff_initial_s: float = 0.5
    backoff_max_s: float = 8.0


@dataclass(frozen=True)
class ProcessConfig:
    """Everything the supervisor and the runner need to know about one process."""

    name: str
    host: str
    module: str  # python module defining make_node(proc, profile) or main(proc, profile)
    source_file: Path  # the YAML file the process was defined in (for error messages)
    rate_hz: float | None = None  # periodic rate, or the expected rate of a message-driven loop
    deadline_ms: float | None = None
    inputs: dict[str, ChannelConfig] = field(default_factory=dict)  # role -> channel
    outputs: dict[str, ChannelConfig] = field(default_factory=dict)
    depends_on: tuple[str, ...] = ()
    ready_channel: ChannelConfig | None = None  # first message here = ready
    ready_timeout_s: float = 10.0
    restart: RestartPolicy = field(default_factory=RestartPolicy)
    required: bool = True
    cpu_affinity: tuple[int, ...] | None = None
    nice: int | None = None
    gc: Literal["on", "freeze"] = "freeze"  # control loops freeze and disable the collector
    params: dict[str, Any] = field(default_factory=dict)  # free-form, validated by the process
    gains_file: Path | None = None
    harness_delay_ms: float = 0.0  # modelled compute latency in the deterministic harness

    def key(self, *parts: str) -> str:
        """Dotted config key for error messages, e.g. ``processes.osc.params.kp``."""
        return ".".join(("processes", self.name, *parts))


@dataclass(frozen=True)
class HostConfig:
    name: str
    address: str
    description: str = ""


@dataclass(frozen=True)
class Profile:
    """A launch profile: which processes run, in which mode, over which bus."""

    name: str
    path: Path
    hw_config_dir: Path
    mode: Mode
    lcm_url: str
    hosts: dict[str, HostConfig]
    channels: dict[str, ChannelConfig]
    processes: dict[str, ProcessConfig]  # the catalog
    launch: tuple[str, ...]  # names to run, in the order given (the supervisor sorts by deps)
    timing_report_hz: float = 10.0
    status_channel: str = "SUPERVISOR_STATUS"
    orders_channel: str = "SUPERVISOR_ORDERS"
    timing_channel: str = "TIMING"

    def resolve(self, relative: str | Path) -> Path:
        """A path from a config value, relative to the hw_config folder."""
        p = Path(relative)
        return p if p.is_absolute() else (self.hw_config_dir / p)
