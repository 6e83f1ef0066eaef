"""Typed, validated views of hw_config: what the loader in ``runtime.config`` returns."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal, TypeVar

from runtime.errors import ConfigError
from runtime.params import spec

W = TypeVar("W")
Mode = Literal["realtime", "lockstep"]
RestartKind = Literal["always", "on-failure", "never"]


#: the LCM domain shared by every host (``runtime.bus.NETWORK``)
NETWORK = "network"


@dataclass(frozen=True)
class ChannelConfig:
    """One named link: an LCM channel, or a UDP address the receiver binds and senders target.

    ``scope`` says which LCM domain carries it: ``network`` (it crosses between hosts, ttl 1:
    every ``NETWORK_*`` channel, and those declared so), a host name (it lives on that host's
    bus, as a camera's cable ends at one computer), or "" (it stays on the host of the process
    that publishes it, ttl 0).
    """

    key: str
    name: str  # LCM channel name, or "udp:HOST:PORT" for a UDP link
    udp: tuple[str, int] | None = None
    scope: str = ""

    @property
    def is_udp(self) -> bool:
        return self.udp is not None

    @property
    def ttl(self) -> int:
        """LCM ttl: 1 for channels that cross NUC <-> laptop, else 0."""
        return 1 if self.scope == NETWORK or self.name.startswith("NETWORK_") else 0


@dataclass(frozen=True)
class RestartPolicy:
    """When and how fast the supervisor restarts a process, and when it gives up: a process's
    ``restart:`` in processes.yaml, read as it is (``runtime.params.read``)."""

    policy: RestartKind = "on-failure"
    #: within window_s; one more and the process is in crash_loop
    max_restarts: int = spec(5, lo=0, hi=1000)
    window_s: float = spec(60.0, lo=0.0, lo_open=True, unit="s")
    backoff_initial_s: float = spec(0.5, lo=0.0, unit="s")
    backoff_max_s: float = spec(8.0, lo=0.0, unit="s")
    #: keep a spare copy of the process set up and waiting (``cassie run --standby``): a
    #: crash is answered by waking it, ready in milliseconds instead of a cold start
    standby: bool = False


@dataclass(frozen=True)
class ProcessConfig:
    """Everything the supervisor and the runner need to know about one process."""

    name: str
    host: str
    module: str  # python module defining make_node(proc, profile) or main(proc, profile)
    source_file: Path  # the YAML file the process was defined in (for error messages)
    description: str = ""  # what it does, in a line (`cassie list PROFILE`)
    rate_hz: float | None = None  # periodic rate, or the expected rate of a message-driven loop
    deadline_ms: float | None = None
    inputs: dict[str, ChannelConfig] = field(default_factory=dict)  # role -> channel
    outputs: dict[str, ChannelConfig] = field(default_factory=dict)
    depends_on: tuple[str, ...] = ()
    ready_timeout_s: float = 10.0  # its first TIMING message (sent after setup) within this
    restart: RestartPolicy = field(default_factory=RestartPolicy)
    required: bool = True
    cpu_affinity: tuple[int, ...] | None = None
    nice: int | None = None
    rt_priority: int | None = None  # SCHED_FIFO priority (1-99) the process asks for, if any
    gc: Literal["on", "freeze"] = "freeze"  # control loops freeze and disable the collector
    #: message-driven: at most one tick per 1/max_rate_hz of sim time (the first trigger of
    #: each slot; the rest are counted as rate-skipped), as a 1 kHz OSC on 2 kHz states
    max_rate_hz: float | None = None
    #: output role -> at most this many messages per second of sim time (debug streams)
    output_rate_hz: dict[str, float] = field(default_factory=dict)
    params: dict[str, Any] = field(default_factory=dict)  # free-form, validated by the process
    #: input role -> field -> (lo, hi): a message outside is rejected at the edge
    #: (``runtime.validate``), as is any message with a non-finite float
    limits: dict[str, dict[str, tuple[float, float]]] = field(default_factory=dict)
    gains_file: Path | None = None
    harness_delay_ms: float = 0.0  # modelled compute latency in the deterministic harness
    #: the values a profile's ``overrides:`` wrote: their key under the process (``rate_hz``,
    #: ``params.push.force_n``) -> the profile file that wrote it (the last one, when several
    #: did); an error about one of them names that file (``blame``)
    overridden: dict[str, Path] = field(default_factory=dict)

    def key(self, *parts: str) -> str:
        """Dotted config key for error messages, e.g. ``processes.osc.params.kp``."""
        return ".".join(("processes", self.name, *parts))

    def blame(self, exc: ConfigError) -> ConfigError:
        """``exc`` naming the profile file and the ``overrides:`` key that wrote the value it
        is about, when one did (``blame_override``)."""
        return blame_override(exc, self.name, self.overridden)


def blame_override(exc: ConfigError, process: str, overridden: dict[str, Path]) -> ConfigError:
    """``exc`` naming where its value was written: ``overrides.PROCESS.KEY`` of the profile
    file that overrode it (``overridden``: ``ProcessConfig.overridden``), when one did, else
    ``exc`` as it is; so an error points at the line to fix, not at the catalog entry the
    override replaced."""
    prefix = f"processes.{process}."
    if not exc.key.startswith(prefix):
        return exc
    rest = exc.key[len(prefix):]
    file = writer(rest, overridden)
    if file is None:
        return exc
    return ConfigError(str(file), f"overrides.{process}.{rest}", exc.problem, exc.allowed)


def writer(key: str, written: Mapping[str, W]) -> W | None:
    """Who wrote the value at the dotted ``key``, of ``written`` (dotted key -> its writer, in
    the order written): the writer of ``key`` or of the nearest value it is part of (a list's
    item, a mapping written whole); else the last writer of a key inside it (a mapping put
    together with that value); else None. How an error is traced back to its override."""
    covering = [at for at in written if key == at or key.startswith((at + ".", at + "["))]
    if covering:
        return written[max(covering, key=len)]  # the most specific
    inside = [by for at, by in written.items() if at.startswith(key + ".")]
    return inside[-1] if inside else None


@dataclass(frozen=True)
class HostConfig:
    name: str
    address: str
    description: str = ""
    lcm_port_offset: int = 0  # this host's own LCM domain: the network URL's port + this
    #: the CPUs that stand in for this host's computer: every process on the host is pinned
    #: to them (unless it sets its own cpu_affinity); None: anywhere
    cpus: tuple[int, ...] | None = None
    #: its processes are started by the deputy on that host (``cassie deputy --host NAME``,
    #: ``runtime.deputy``), not by the supervisor itself: procman's sheriff/deputy split
    deputy: bool = False


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
    supervisor_host: str = ""  # where the supervisor and its helpers (loggers) run
    status_channel: str = "SUPERVISOR_STATUS"
    orders_channel: str = "SUPERVISOR_ORDERS"
    timing_channel: str = "TIMING"
    deputy_orders_channel: str = "DEPUTY_ORDERS"
    deputy_status_channel: str = "DEPUTY_STATUS"
    #: LCM domain name ("network", host names) -> URL; empty: everything on ``lcm_url``
    domains: dict[str, str] = field(default_factory=dict)
    #: LCM channel name -> its domain (for the launched processes); unlisted: "network"
    channel_domains: dict[str, str] = field(default_factory=dict)
    #: real-time factor of a ``realtime`` run: sim seconds per wall second (0.5 on a machine
    #: too slow for 1); periods, deadlines and wall-clock budgets scale by 1 / rtf
    rtf: float = 1.0
    #: the URL before the instance offset (``$CASSIE_INSTANCE``) moved it: what a process
    #: started with the same instance must be given as ``$CASSIE_LCM_URL``
    base_lcm_url: str = ""

    def resolve(self, relative: str | Path) -> Path:
        """A path from a config value, relative to the hw_config folder."""
        p = Path(relative)
        return p if p.is_absolute() else (self.hw_config_dir / p)
