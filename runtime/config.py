"""Loading and validating hw_config: hosts, channels, processes, gains and launch profiles.

A launch profile is one YAML file that includes others (``include:``, relative to it). The
sections ``lcm``, ``hosts``, ``channels`` and ``processes`` are merged entry by entry, later
files winning; ``overrides`` in the profile patch single processes. Every value is checked here,
at load time, and every error names the file, the dotted key and what is allowed: each file
shape is a frozen dataclass (``ProfileFile``, ``HostEntry``, ``ChannelEntry``, ``ProcessEntry``)
read with ``runtime.params.read``, as a process's params and gains are, and the sections of
user-named entries (hosts, channels, processes) are read entry by entry; what depends on the
rest of the profile (a process's host, its channels) is checked once all is read. An error in a
value that a profile's ``overrides:`` wrote names that profile and the override's key.
The LCM URL can be overridden with the ``CASSIE_LCM_URL`` environment variable (tests use it
to isolate runs on their own multicast port).
"""

from __future__ import annotations

import copy
import importlib.util
import ipaddress
import os
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any, Literal, TypeVar
from urllib.parse import urlparse, urlunparse

import yaml

from runtime.config_types import (
    NETWORK,
    ChannelConfig,
    HostConfig,
    Mode,
    ProcessConfig,
    Profile,
    RestartPolicy,
    blame_override,
)
from runtime.errors import ConfigError
from runtime.params import read, spec
from runtime.route import DEFAULT_URL

__all__ = ["HW_CONFIG_DIR", "ConfigError", "find_profile", "load_profile", "load_yaml"]

HW_CONFIG_DIR = Path(__file__).resolve().parent.parent / "hw_config"
T = TypeVar("T")

#: how the hosts' local (ttl-0) traffic is kept apart on this one machine: ``ports`` gives each
#: host a multicast port of its own (the network URL's port + the host's lcm_port_offset), as
#: the real robot's ttl 0 keeps the NUC's 2 kHz traffic off the laptop; ``shared`` puts every
#: host on the one network URL (every process hears everything)
HOST_BUSES = ("ports", "shared")


class _UniqueKeyLoader(yaml.SafeLoader):
    """PyYAML's safe loader, except that a mapping with a key twice is an error (PyYAML keeps
    the last value silently: a gain typed twice, the first one ignored)."""

    def construct_mapping(self, node: yaml.MappingNode, deep: bool = False) -> dict[Any, Any]:
        seen: dict[Any, Any] = {}
        for key_node, _ in node.value:
            key = self.construct_object(key_node, deep=deep)
            if key in seen:
                raise yaml.constructor.ConstructorError(
                    "while reading a mapping", node.start_mark,
                    f"found the key {key!r} twice (first on line {seen[key]}); remove one",
                    key_node.start_mark)
            seen[key] = key_node.start_mark.line + 1
        return super().construct_mapping(node, deep)


def safe_load(text: str) -> Any:
    """``yaml.safe_load`` that rejects duplicate keys: every hw_config reader uses it."""
    return yaml.load(text, Loader=_UniqueKeyLoader)


def load_yaml(path: Path) -> dict[str, Any]:
    """Read a YAML mapping, with errors that name the file."""
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError as exc:
        raise ConfigError(str(path), "<file>", "file not found") from exc
    try:
        data = safe_load(text)
    except yaml.YAMLError as exc:
        raise ConfigError(str(path), "<file>", f"not valid YAML: {exc}") from exc
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise ConfigError(str(path), "<top level>", f"must be a mapping, got {type(data).__name__}")
    return data


# process_gains is no process's own any more (each reads its params and gains as
# runtime.params dataclasses, through runtime.builder): it stays for the estimator benchmark's
# baseline, which imports an older revision's estimator beside this tree's runtime
# (tools/benchmarks/estimator.py's baseline_state_estimator).


def process_gains(proc: ProcessConfig, default: Path, allow_params: bool = False) -> Path:
    """The gains file of ``proc`` (absolute since load time), or ``default``. Processes whose
    settings all live in their gains file pass ``allow_params=False``: any ``params`` key is
    then an error that says where the settings belong."""
    if not allow_params:
        for key in proc.params:
            raise ConfigError(
                str(proc.source_file),
                proc.key("params", key),
                "unknown parameter",
                "(none: this process's settings live in its gains file)",
            )
    return Path(proc.gains_file) if proc.gains_file is not None else default


def find_profile(name_or_path: str) -> Path:
    """A profile by path, or by name in hw_config/ (``sim`` -> ``hw_config/sim.yaml``)."""
    p = Path(name_or_path)
    if p.is_file():  # a file only: `sim` must not match the sim/ package folder
        return p.resolve()
    for candidate in (HW_CONFIG_DIR / name_or_path, HW_CONFIG_DIR / f"{name_or_path}.yaml"):
        if candidate.is_file():
            return candidate.resolve()
    known = sorted(x.stem for x in HW_CONFIG_DIR.glob("*.yaml") if is_profile(x))
    raise ConfigError(
        name_or_path,
        "<profile>",
        "no such profile file",
        allowed=", ".join(known) + " (or a path to a profile YAML)",
    )


#: the environment variable naming this stack's instance on a shared machine (0, 1, ...)
INSTANCE_ENV = "CASSIE_INSTANCE"
#: each instance moves every port (LCM domains, UDP links) up by this much
INSTANCE_PORT_STEP = 20


def instance() -> int:
    """This stack's instance (``$CASSIE_INSTANCE``, 0 when unset): two stacks on one machine
    with different instances use different ports everywhere, so neither hears the other."""
    raw = os.environ.get(INSTANCE_ENV, "").strip()
    if not raw:
        return 0
    if not raw.isdigit() or not 0 <= int(raw) <= 99:
        raise ConfigError("the environment", INSTANCE_ENV, f"{raw!r} is not an instance",
                          "an integer 0 .. 99 (each moves every port up by "
                          f"{INSTANCE_PORT_STEP}), or unset")
    return int(raw)


def is_profile(path: Path) -> bool:
    """Whether a YAML file is a launch profile (it names what to launch)."""
    try:
        return "launch" in load_yaml(path)
    except ConfigError:
        return False


def _read(cls: type[T], data: Any, file: Path | str, key: str = "") -> T:
    """``runtime.params.read`` with hw_config's one rule on top: a key set to null takes its
    default (``rate_hz: ~`` in an override unsets the catalog's value)."""
    if isinstance(data, Mapping):
        data = {k: v for k, v in data.items() if v is not None}
    return read(cls, data, file, key)


def _lcm_name(name: str, file: str, key: str) -> str:
    """``name`` if it is a valid LCM channel name, else a ConfigError naming ``key``."""
    if not name.replace("_", "").isalnum():
        raise ConfigError(file, key, f"{name!r} is not a valid LCM channel name",
                          "letters, digits and underscores")
    return name


def _some_cpus(cpus: tuple[int, ...] | None, owner: str, key: str) -> None:
    """A ConfigError when a CPU list is empty: it would pin the process to no CPU (leave the
    key out for any CPU)."""
    if cpus == ():
        raise ConfigError(owner, key, "must be a list of CPU numbers, got []",
                          f"CPU numbers 0..{(os.cpu_count() or 1) - 1} on this machine")


@dataclass(frozen=True)
class LcmSection:
    """``lcm:`` of a profile file: the network's URL and how the hosts' buses are kept apart
    (each unset key leaves what an earlier file said)."""

    url: str | None = None
    host_buses: str | None = spec(None, choices=HOST_BUSES)

    def __post_init__(self) -> None:
        if self.url is not None and not self.url.startswith(("udpm://", "memq://")):
            raise ConfigError("<LcmSection>", "url", f"{self.url!r} is not an LCM URL",
                              "udpm://GROUP:PORT (or memq:// for one process)")


@dataclass(frozen=True)
class SupervisorSection:
    """``supervisor:`` of a profile: the host it runs on and the channels it talks on."""

    host: str | None = None  # a host of hosts.yaml (default: the laptop, when there is one)
    status_channel: str = "SUPERVISOR_STATUS"
    orders_channel: str = "SUPERVISOR_ORDERS"
    timing_channel: str = "TIMING"
    deputy_orders_channel: str = "DEPUTY_ORDERS"
    deputy_status_channel: str = "DEPUTY_STATUS"

    def __post_init__(self) -> None:
        for f in fields(self):
            if f.name.endswith("_channel"):
                _lcm_name(getattr(self, f.name), "<SupervisorSection>", f.name)


@dataclass(frozen=True)
class ProfileFile:
    """One file of a launch profile (the profile, or a file it includes) as written. The
    sections ``hosts``, ``channels`` and ``processes`` merge across the files entry by entry,
    later files winning, and each entry is read on its own (``HostEntry``, ``_channel``,
    ``ProcessEntry``); ``overrides`` patch processes, in include order; ``lcm`` keys hold
    until a later file sets them; the other keys count in the profile's own file."""

    profile: str | None = None  # the profile's name (default: its file's stem)
    description: str = ""
    include: tuple[str, ...] = ()  # files relative to this one, read before it
    mode: Mode = "realtime"
    launch: tuple[str, ...] | None = None  # the processes to launch: a profile names them
    overrides: dict[str, dict[str, Any]] = spec(default_factory=dict)  # process -> its keys
    timing_report_hz: float = spec(10.0, lo=0.1, hi=100.0, unit="Hz")
    rtf: float = spec(1.0, lo=0.01, hi=1.0)  # sim seconds per wall second (realtime only)
    lcm: LcmSection = field(default_factory=LcmSection)
    hosts: dict[str, Any] = spec(default_factory=dict)  # name -> HostEntry
    channels: dict[str, Any] = spec(default_factory=dict)  # key -> name, or ChannelEntry
    processes: dict[str, Any] = spec(default_factory=dict)  # name -> ProcessEntry
    supervisor: SupervisorSection = field(default_factory=SupervisorSection)

    def __post_init__(self) -> None:
        if self.rtf != 1.0 and self.mode != "realtime":
            raise ConfigError("<ProfileFile>", "rtf", f"a real-time factor of {self.rtf:g} "
                              "needs mode: realtime", "1.0 in lockstep")


@dataclass(frozen=True)
class HostEntry:
    """One entry of ``hosts:`` (hosts.yaml): a computer of the robot, emulated on this one."""

    address: str
    description: str = ""
    #: its own LCM domain: the network URL's port + this (a host without one gets the next
    #: port in list order); below the instance step, so no port is the next instance's
    lcm_port_offset: int = spec(0, lo=0, hi=INSTANCE_PORT_STEP - 1)
    cpus: tuple[int, ...] | None = spec(None, lo=0)  # the CPUs standing in for its computer
    deputy: bool = False  # its processes are run by `cassie deputy --host NAME` there

    def __post_init__(self) -> None:
        if not self.address:
            raise ConfigError("<HostEntry>", "address", "must be a non-empty string, got ''")
        _some_cpus(self.cpus, "<HostEntry>", "cpus")


@dataclass(frozen=True)
class ChannelEntry:
    """One entry of ``channels:`` written as a mapping (a bare string is an LCM channel's
    name): a UDP link ``udp: HOST:PORT``, or an LCM ``name`` with its ``scope``."""

    udp: str | None = None  # HOST (a host of hosts.yaml, or an IPv4 address) : PORT
    name: str | None = None
    scope: str = ""  # network, host (the publisher's, as ""), or the name of a host


@dataclass(frozen=True)
class ReadyEntry:
    """``ready:`` of a process: how long the supervisor waits for its first TIMING message."""

    timeout_s: float = spec(15.0, lo=0.0, lo_open=True, unit="s")


@dataclass(frozen=True)
class ProcessEntry:
    """One entry of ``processes:`` (processes.yaml, with the profiles' ``overrides:`` laid
    over it) as written; ``_process`` checks it against the hosts and channels."""

    host: str  # a host of hosts.yaml
    module: str  # the Python module that runs it
    description: str = ""
    rate_hz: float | None = spec(None, lo=0.0, hi=100000.0, lo_open=True, unit="Hz")
    deadline_ms: float | None = spec(None, lo=0.0, hi=60000.0, lo_open=True, unit="ms")
    inputs: dict[str, str] = spec(default_factory=dict)  # role -> a key of channels.yaml
    outputs: dict[str, str] = spec(default_factory=dict)
    depends_on: tuple[str, ...] = ()
    ready: ReadyEntry = field(default_factory=ReadyEntry)
    restart: RestartPolicy = field(default_factory=RestartPolicy)
    required: bool = True
    cpu_affinity: tuple[int, ...] | None = spec(None, lo=0)  # default: its host's cpus
    nice: int | None = spec(None, lo=-20, hi=19)
    rt_priority: int | None = spec(None, lo=1, hi=99)
    gc: Literal["on", "freeze"] = "freeze"
    max_rate_hz: float | None = spec(None, lo=0.0, hi=100000.0, lo_open=True, unit="Hz")
    #: output role -> at most this many messages per second of sim time
    output_rate_hz: dict[str, float] = spec(default_factory=dict, lo=0.0, hi=100000.0,
                                            lo_open=True, unit="Hz")
    params: dict[str, Any] = spec(default_factory=dict)  # the module's Params (builder)
    gains: str | None = None  # a gains file, relative to the file that names it
    harness_delay_ms: float = spec(0.0, lo=0.0, hi=1000.0, unit="ms")
    #: input role -> field -> [lo, hi] (or ``utime_step_s``: seconds): ``runtime.validate``
    limits: dict[str, dict[str, Any]] = spec(default_factory=dict)

    def __post_init__(self) -> None:
        _some_cpus(self.cpu_affinity, "<ProcessEntry>", "cpu_affinity")


def _written(override: Mapping[str, Any], base: Any, at: str = "") -> Iterator[str]:
    """The dotted keys an override laid over ``base`` writes: down to its values where it
    merges into a mapping of ``base``, a whole value where ``base`` has none to merge into."""
    for k, v in override.items():
        path = f"{at}.{k}" if at else str(k)
        below = base.get(k) if isinstance(base, Mapping) else None
        if isinstance(v, Mapping) and v and isinstance(below, Mapping):
            yield from _written(v, below, path)
        else:
            yield path


def _merge(dst: dict[str, Any], src: dict[str, Any]) -> dict[str, Any]:
    """Deep-merge ``src`` into a copy of ``dst``: mappings merge, everything else replaces."""
    out = copy.deepcopy(dst)
    for k, v in src.items():
        if isinstance(v, dict) and isinstance(out.get(k), dict):
            out[k] = _merge(out[k], v)
        else:
            out[k] = copy.deepcopy(v)
    return out


def load_profile(path: str | Path) -> Profile:
    """Load, merge and validate a launch profile and everything it includes."""
    path = find_profile(str(path))
    hw_dir = path.parent
    sections: dict[str, dict[str, tuple[Any, Path]]] = {
        "hosts": {},
        "channels": {},
        "processes": {},
    }
    lcm_url: tuple[str, Path] | None = None
    host_buses: tuple[str, Path] = ("ports", path)
    seen: list[Path] = []
    stack: list[Path] = []
    all_overrides: list[tuple[str, dict[str, Any], Path]] = []  # in include order, top last

    def absorb(file: Path) -> ProfileFile | None:
        """Read ``file`` and, first, the files it includes (None: read already)."""
        nonlocal lcm_url, host_buses
        if file in stack:
            chain = " -> ".join(p.name for p in [*stack, file])
            raise ConfigError(str(file), "include", f"files include each other in a cycle: {chain}")
        if file in seen:  # included twice along different paths: once is enough
            return None
        seen.append(file)
        stack.append(file)
        doc = _read(ProfileFile, load_yaml(file), file)
        for inc in doc.include:
            inc_path = (file.parent / inc).resolve()
            if not inc_path.exists():
                raise ConfigError(
                    str(file),
                    "include",
                    f"included file {inc!r} does not exist",
                    allowed=", ".join(sorted(p.name for p in file.parent.glob("*.yaml"))),
                )
            absorb(inc_path)
        all_overrides.extend((pname, value, file) for pname, value in doc.overrides.items())
        if doc.lcm.url is not None:
            lcm_url = (doc.lcm.url, file)
        if doc.lcm.host_buses is not None:
            host_buses = (doc.lcm.host_buses, file)
        for section, entries in sections.items():
            for name, value in getattr(doc, section).items():
                entries[name] = (value, file)
        stack.pop()
        return doc

    top = absorb(path)
    assert top is not None  # (the first file read)
    url = os.environ.get("CASSIE_LCM_URL") or (
        lcm_url[0] if lcm_url else DEFAULT_URL
    )
    base_url = url
    if (n := instance()) and url.startswith("udpm://"):
        base = urlparse(url)
        url = urlunparse(base._replace(
            netloc=f"{base.hostname}:{(base.port or 7667) + INSTANCE_PORT_STEP * n}"))

    hosts = {}
    for hname, (value, file) in sections["hosts"].items():
        h = _read(HostEntry, value, file, f"hosts.{hname}")
        hosts[hname] = HostConfig(hname, h.address, h.description, h.lcm_port_offset, h.cpus,
                                  h.deputy)

    channels = {
        cname: _channel(cname, value, file, hosts)
        for cname, (value, file) in sections["channels"].items()
    }
    for cname, (_, file) in sections["channels"].items():
        scope = channels[cname].scope
        if scope and scope != NETWORK and scope not in hosts:
            raise ConfigError(str(file), f"channels.{cname}.scope", f"unknown scope {scope!r}",
                              allowed=", ".join(["network", "host", *sorted(hosts)]))

    for pname, _, ofile in all_overrides:
        if pname not in sections["processes"]:
            raise ConfigError(
                str(ofile),
                f"overrides.{pname}",
                "no such process",
                allowed=", ".join(sorted(sections["processes"])),
            )
    processes = {}
    for pname, (value, file) in sections["processes"].items():
        raw, overridden = value, {}
        for name, ov, ofile in all_overrides:
            if name != pname:
                continue
            for k in _written(ov, raw):  # the last file to write a key is the one to blame
                overridden.pop(k, None)
                overridden[k] = ofile
            raw = _merge(raw, ov) if isinstance(raw, dict) else raw
        try:
            entry = _read(ProcessEntry, raw, file, f"processes.{pname}")
            processes[pname] = _process(pname, entry, file, hosts, channels, overridden)
        except ConfigError as exc:
            raise blame_override(exc, pname, overridden) from None

    launch = top.launch
    if not launch:
        raise ConfigError(
            str(path),
            "launch",
            "must be a non-empty list of process names, got "
            f"{None if launch is None else list(launch)!r}",
            allowed=", ".join(sorted(processes)),
        )
    for i, pname in enumerate(launch):
        if pname not in processes:
            raise ConfigError(str(path), f"launch[{i}]", f"no process named {pname!r}",
                              allowed=", ".join(sorted(processes)))
    for pname in launch:
        for dep in processes[pname].depends_on:
            if dep not in launch:
                raise ConfigError(
                    str(path),
                    "launch",
                    f"{pname} depends on {dep}, which this profile does not launch",
                    allowed=", ".join(sorted(processes)),
                )
    domains, channel_domains = _domains(url, host_buses, hosts, channels, processes, launch)
    sup = top.supervisor
    sup_host = ""
    if hosts:
        sup_host = sup.host if sup.host is not None else "laptop" if "laptop" in hosts else ""
        if sup.host is not None and sup.host not in hosts:
            raise ConfigError(str(path), "supervisor.host",
                              f"{sup.host!r} is not one of the allowed values",
                              ", ".join(sorted(hosts)))
    # Relative paths in params (terrains, ...) resolve against hw_config/ when the profile builds
    # on the product configuration, else against the profile's own folder.
    if any(HW_CONFIG_DIR.resolve() in f.parents for f in seen):
        hw_dir = HW_CONFIG_DIR.resolve()
    return Profile(
        name=top.profile or path.stem,
        path=path,
        hw_config_dir=hw_dir,
        mode=top.mode,
        lcm_url=url,
        base_lcm_url=base_url,
        hosts=hosts,
        channels=channels,
        processes=processes,
        launch=launch,
        timing_report_hz=top.timing_report_hz,
        status_channel=sup.status_channel,
        orders_channel=sup.orders_channel,
        timing_channel=sup.timing_channel,
        deputy_orders_channel=sup.deputy_orders_channel,
        deputy_status_channel=sup.deputy_status_channel,
        domains=domains,
        channel_domains=channel_domains,
        rtf=top.rtf,
        supervisor_host=sup_host,
    )



def _domains(
    url: str,
    host_buses: tuple[str, Path],
    hosts: dict[str, HostConfig],
    channels: dict[str, ChannelConfig],
    processes: dict[str, ProcessConfig],
    launch: Sequence[str],
) -> tuple[dict[str, str], dict[str, str]]:
    """The LCM domains (name -> URL) and the domain of every channel, checked against the
    launched processes: a host-local channel is published from one host only, and only
    processes on that host subscribe to it (on the robot, ttl 0 never leaves the host)."""
    mode, mode_file = host_buses
    domains = {NETWORK: url}
    if url.startswith("udpm://"):
        base = urlparse(url)
        for i, h in enumerate(hosts.values()):
            if mode == "shared":
                domains[h.name] = url
                continue
            # a host without an offset gets the next port, in the order the hosts are listed
            port = (base.port or 7667) + (h.lcm_port_offset or i + 1)
            domains[h.name] = urlunparse(base._replace(netloc=f"{base.hostname}:{port}"))
        ports = [d for d in domains.values()]
        if mode == "ports" and len(set(ports)) != len(ports):
            raise ConfigError(str(mode_file), "hosts", "two hosts share an lcm_port_offset",
                              allowed="a different offset for each host")
    else:  # memq:// (one process): one bus
        domains.update({h: url for h in hosts})
    pubs: dict[str, set[str]] = {}
    subs: dict[str, list[tuple[ProcessConfig, str]]] = {}
    for pname in launch:
        proc = processes[pname]
        for ch in proc.outputs.values():
            if not ch.is_udp:
                pubs.setdefault(ch.name, set()).add(proc.host)
        for role, ch in proc.inputs.items():
            if not ch.is_udp:
                subs.setdefault(ch.name, []).append((proc, role))
    out: dict[str, str] = {}
    for ch in channels.values():
        if ch.is_udp:
            continue
        if ch.ttl == 1:
            domain = NETWORK
        elif ch.scope:
            domain = ch.scope
        else:
            where = pubs.get(ch.name) or {p.host for p, _ in subs.get(ch.name, [])}
            if len(where) > 1:
                proc = next(p for p, _ in subs.get(ch.name, [])) if ch.name in subs else None
                file = proc.source_file if proc else mode_file
                raise ConfigError(
                    str(file), f"channels.{ch.key}",
                    f"{ch.name} is local to one host (ttl 0) but is used on hosts "
                    f"{', '.join(sorted(where))}",
                    allowed="a NETWORK_ name, `scope: network`, or `scope: HOST` in "
                    "channels.yaml",
                )
            domain = next(iter(where)) if where else NETWORK
        out[ch.name] = domain
        if domain == NETWORK:
            continue
        for proc, role in subs.get(ch.name, []):
            if proc.host != domain:
                raise proc.blame(ConfigError(
                    str(proc.source_file), proc.key("inputs", role),
                    f"{ch.name} stays on host {domain} (ttl 0), but {proc.name} runs on "
                    f"{proc.host} and would never receive it",
                    allowed="a channel that crosses hosts (NETWORK_ name or `scope: network` "
                    "in channels.yaml), or run the process on " + domain,
                ))
    return domains, out


def _is_ip(text: str) -> bool:
    try:
        ipaddress.IPv4Address(text)
    except ValueError:
        return False
    return True


def _channel(cname: str, value: Any, file: Path,
             hosts: dict[str, HostConfig] | None = None) -> ChannelConfig:
    """One entry of ``channels``; a UDP link's HOST may name a host of hosts.yaml (its
    address: the NUC's and the target PC's, as on the robot)."""
    key = f"channels.{cname}"
    if isinstance(value, str):
        return ChannelConfig(cname, _lcm_name(value, str(file), key))
    entry = _read(ChannelEntry, value, file, key)
    if entry.udp is not None:
        host, _, port_s = entry.udp.rpartition(":")
        if not host or not port_s.isdigit() or not 0 < int(port_s) < 65536:
            raise ConfigError(str(file), f"{key}.udp", f"{entry.udp!r} is not HOST:PORT",
                              allowed="e.g. 127.0.0.1:25000")
        port = int(port_s) + INSTANCE_PORT_STEP * instance()
        if hosts and host in hosts:
            host = hosts[host].address
        elif hosts is not None and not _is_ip(host):
            raise ConfigError(str(file), f"{key}.udp", f"{host!r} is neither a host of "
                              "hosts.yaml nor an IPv4 address",
                              allowed=", ".join(sorted(hosts or {})) + " or a.b.c.d")
        return ChannelConfig(cname, f"udp:{host}:{port}", udp=(host, port))
    if entry.name is None:
        raise ConfigError(str(file), f"{key}.name", "is required",
                          "an LCM channel name (or udp: HOST:PORT for a UDP link)")
    name = _lcm_name(entry.name, str(file), f"{key}.name")
    return ChannelConfig(cname, name, scope="" if entry.scope == "host" else entry.scope)


def _process(
    pname: str,
    d: ProcessEntry,
    file: Path,
    hosts: dict[str, HostConfig],
    channels: dict[str, ChannelConfig],
    overridden: dict[str, Path],
) -> ProcessConfig:
    """The ProcessConfig of entry ``d`` of ``file``: its host, channels, rates' roles, gains
    file and limits checked against the rest of the profile."""
    key = f"processes.{pname}"

    def fail(sub: str, problem: str, allowed: str | None = None) -> ConfigError:
        return ConfigError(str(file), f"{key}.{sub}", problem, allowed)

    if hosts and d.host not in hosts:
        raise fail("host", f"{d.host!r} is not one of the allowed values", ", ".join(sorted(hosts)))
    if not d.module or importlib.util.find_spec(d.module.split(".")[0]) is None:
        raise fail("module", f"no importable Python package for {d.module!r}")

    def ports(section: str, table: dict[str, str]) -> dict[str, ChannelConfig]:
        out: dict[str, ChannelConfig] = {}
        roles: dict[str, str] = {}
        for role, cname in table.items():
            if cname not in channels:
                raise fail(f"{section}.{role}", f"unknown channel {cname!r}",
                           allowed=", ".join(sorted(channels)))
            ch = channels[cname]
            if ch.name in roles:  # two roles on one channel: one stream taken as two
                raise fail(f"{section}.{role}", f"channel {ch.name} is already its "
                           f"{section[:-1]} {roles[ch.name]!r}", allowed="one role per channel")
            roles[ch.name] = role
            out[role] = ch
        return out

    inputs, outputs = ports("inputs", d.inputs), ports("outputs", d.outputs)
    for role in d.output_rate_hz:
        if role not in outputs:
            raise fail(f"output_rate_hz.{role}", "not an output of this process",
                       allowed=", ".join(sorted(outputs)))
    gains_file = None
    if d.gains is not None:
        gains_file = (file.parent / d.gains).resolve()
        if not d.gains or not gains_file.is_file():
            raise fail("gains", f"gains file {d.gains!r} does not exist",
                       allowed="a path relative to hw_config/, e.g. gains/osc.yaml")
    limits: dict[str, dict[str, tuple[float, float]]] = {}
    for role, bounds in d.limits.items():
        if role not in inputs:
            raise fail(f"limits.{role}", "not an input of this process",
                       allowed=", ".join(sorted(inputs)))
        limits[role] = {}
        for fname, rng in bounds.items():
            if fname == "utime_step_s":  # the stream's clock (runtime.validate): one number
                if isinstance(rng, bool) or not isinstance(rng, int | float) or not rng > 0:
                    raise fail(f"limits.{role}.utime_step_s", f"must be seconds > 0, got {rng!r}")
                limits[role][fname] = (0.0, float(rng))
                continue
            ok = (isinstance(rng, list) and len(rng) == 2
                  and all(isinstance(x, int | float) and not isinstance(x, bool) for x in rng)
                  and all(x == x for x in rng) and rng[0] <= rng[1])
            if not ok:
                raise fail(f"limits.{role}.{fname}", f"must be [lo, hi], got {rng!r}",
                           allowed="two numbers, lo <= hi")
            limits[role][str(fname)] = (float(rng[0]), float(rng[1]))
    return ProcessConfig(
        name=pname,
        host=d.host,
        module=d.module,
        source_file=file,
        description=d.description,
        rate_hz=d.rate_hz,
        deadline_ms=d.deadline_ms,
        inputs=inputs,
        outputs=outputs,
        depends_on=d.depends_on,
        ready_timeout_s=d.ready.timeout_s,
        restart=d.restart,
        required=d.required,
        cpu_affinity=d.cpu_affinity or (hosts[d.host].cpus if d.host in hosts else None),
        nice=d.nice,
        rt_priority=d.rt_priority,
        max_rate_hz=d.max_rate_hz,
        output_rate_hz=d.output_rate_hz,
        gc=d.gc,
        params=d.params,
        limits=limits,
        gains_file=gains_file,
        harness_delay_ms=d.harness_delay_ms,
        overridden=overridden,
    )



def check_depends(profile: Profile) -> list[str]:
    """The profile's processes in dependency order (dependencies first); ConfigError on a cycle."""
    order: list[str] = []
    state: dict[str, int] = {}

    def visit(name: str, chain: list[str]) -> None:
        if state.get(name) == 2:
            return
        if state.get(name) == 1:
            proc = profile.processes[name]
            raise proc.blame(ConfigError(
                str(proc.source_file),
                proc.key("depends_on"),
                "dependency cycle: " + " -> ".join([*chain, name]),
            ))
        state[name] = 1
        proc = profile.processes[name]
        for dep in proc.depends_on:
            if dep not in profile.processes:
                raise proc.blame(ConfigError(
                    str(proc.source_file),
                    proc.key("depends_on"),
                    f"no process named {dep!r}",
                    allowed=", ".join(sorted(profile.processes)),
                ))
            visit(dep, [*chain, name])
        state[name] = 2
        order.append(name)

    for name in profile.launch:
        visit(name, [])
    return order
