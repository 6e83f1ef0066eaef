"""Loading and validating hw_config: hosts, channels, processes, gains and launch profiles.

A launch profile is one YAML file that includes others (``include:``, relative to it). The
sections ``lcm``, ``hosts``, ``channels`` and ``processes`` are merged entry by entry, later
files winning; ``overrides`` in the profile patch single processes. Every value is checked here,
at load time, and every error names the file, the dotted key and what is allowed.
The LCM URL can be overridden with the ``CASSIE_LCM_URL`` environment variable (tests use it
to isolate runs on their own multicast port).
"""

from __future__ import annotations

import copy
import importlib.util
import ipaddress
import os
from pathlib import Path
from typing import Any
from urllib.parse import urlparse, urlunparse

import yaml

from runtime.config_types import (
    NETWORK,
    ChannelConfig,
    HostConfig,
    ProcessConfig,
    Profile,
    RestartPolicy,
)
from runtime.errors import ConfigError
from runtime.route import DEFAULT_URL

__all__ = ["HW_CONFIG_DIR", "ConfigError", "find_profile", "load_profile", "load_yaml"]

HW_CONFIG_DIR = Path(__file__).resolve().parent.parent / "hw_config"

PROFILE_KEYS = {
    "profile",
    "description",
    "include",
    "mode",
    "launch",
    "overrides",
    "timing_report_hz",
    "rtf",
    "lcm",
    "hosts",
    "channels",
    "processes",
    "supervisor",
}
PROCESS_KEYS = {
    "host",
    "module",
    "rate_hz",
    "deadline_ms",
    "inputs",
    "outputs",
    "depends_on",
    "ready",
    "restart",
    "required",
    "cpu_affinity",
    "nice",
    "rt_priority",
    "gc",
    "max_rate_hz",
    "output_rate_hz",
    "params",
    "gains",
    "description",
    "harness_delay_ms",
    "limits",
}
RESTART_KEYS = {"policy", "max_restarts", "window_s", "backoff_initial_s", "backoff_max_s",
                "standby"}
MODES = ("realtime", "lockstep")
#: how the hosts' local (ttl-0) traffic is kept apart on this one machine: ``ports`` gives each
#: host a multicast port of its own (the network URL's port + the host's lcm_port_offset), as
#: the real robot's ttl 0 keeps the NUC's 2 kHz traffic off the laptop; ``shared`` puts every
#: host on the one network URL (every process hears everything)
HOST_BUSES = ("ports", "shared")
RESTART_POLICIES = ("always", "on-failure", "never")


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


# The three readers below are no process's own any more (each reads its params and gains as
# runtime.params dataclasses, through runtime.builder): they stay for the benchmarks' baselines,
# which import an older revision's process code beside this tree's runtime (e.g.
# tools/benchmarks/estimator.py's baseline_state_estimator).


def param_number(proc: ProcessConfig, name: str, *, default: Any = None,
                 lo: float | None = None, hi: float | None = None, lo_open: bool = False,
                 hint: str | None = None) -> Any:
    """``proc.params[name]`` as a number within [lo, hi] (``default`` when absent or null);
    otherwise a ``ConfigError`` naming the file, ``processes.NAME.params.KEY`` and the range
    (with ``hint``, what the value is for). One reader for every process's numeric params."""
    try:
        return _Checker(proc.source_file).number(proc.params, proc.key("params"), name,
                                                 default=default, lo=lo, hi=hi, lo_open=lo_open)
    except ConfigError as exc:
        if hint is None:
            raise
        allowed = f"{exc.allowed}: {hint}" if exc.allowed else hint
        raise ConfigError(exc.file, exc.key, exc.problem, allowed) from None


def param_bool(proc: ProcessConfig, name: str, default: bool) -> bool:
    """``proc.params[name]`` as true or false, else a ``ConfigError`` naming the key."""
    return _Checker(proc.source_file).boolean(proc.params, proc.key("params"), name, default)


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


class _Checker:
    """Small typed accessors that raise ConfigError naming file and key."""

    def __init__(self, file: Path | str) -> None:
        self.file = str(file)

    def fail(self, key: str, problem: str, allowed: str | None = None) -> ConfigError:
        return ConfigError(self.file, key, problem, allowed)

    def mapping(self, value: Any, key: str) -> dict[str, Any]:
        if not isinstance(value, dict):
            raise self.fail(key, f"must be a mapping, got {value!r}")
        return value

    def known_keys(self, d: dict[str, Any], key: str, allowed: set[str]) -> None:
        for k in d:
            if k not in allowed:
                raise self.fail(
                    f"{key}.{k}" if key else str(k),
                    "unknown key",
                    allowed=", ".join(sorted(allowed)),
                )

    def _given(self, d: dict[str, Any], full: str, name: str, default: Any,
               allowed: str | None = None) -> bool:
        """Whether ``d`` gives ``name`` (a null counts as absent); absent with no ``default``
        (``...``) is a ConfigError: ``full`` is required."""
        if name in d and d[name] is not None:
            return True
        if default is ...:
            raise self.fail(full, "is required", allowed)
        return False

    def number(
        self,
        d: dict[str, Any],
        key: str,
        name: str,
        *,
        default: Any = ...,
        lo: float | None = None,
        hi: float | None = None,
        integer: bool = False,
        lo_open: bool = False,
    ) -> Any:
        full = f"{key}.{name}" if key else name
        if not self._given(d, full, name, default):
            return default
        v = d[name]
        kind = "an integer" if integer else "a number"
        if (
            isinstance(v, bool)
            or not isinstance(v, (int, float))
            or (integer and not isinstance(v, int))
        ):
            raise self.fail(full, f"must be {kind}, got {v!r}", allowed=_range(lo, hi, lo_open))
        if (
            v != v
            or (lo is not None and (v < lo or (lo_open and v == lo)))
            or (hi is not None and v > hi)
        ):
            raise self.fail(full, f"out of range: {v!r}", allowed=_range(lo, hi, lo_open))
        return int(v) if integer else float(v)

    def string(
        self,
        d: dict[str, Any],
        key: str,
        name: str,
        *,
        default: Any = ...,
        choices: tuple[str, ...] | None = None,
    ) -> Any:
        full = f"{key}.{name}" if key else name
        allowed = ", ".join(choices) if choices else None
        if not self._given(d, full, name, default, allowed):
            return default
        v = d[name]
        if not isinstance(v, str) or not v:
            raise self.fail(full, f"must be a non-empty string, got {v!r}", allowed=allowed)
        if choices is not None and v not in choices:
            raise self.fail(
                full, f"{v!r} is not one of the allowed values", allowed=", ".join(choices)
            )
        return v

    def boolean(self, d: dict[str, Any], key: str, name: str, default: bool) -> bool:
        v = d.get(name, default)
        if not isinstance(v, bool):
            raise self.fail(f"{key}.{name}", f"must be true or false, got {v!r}", "true, false")
        return v


def _range(lo: float | None, hi: float | None, lo_open: bool = False) -> str | None:
    if lo is None and hi is None:
        return None
    left = "(" if lo_open else "["
    return f"{left}{'-inf' if lo is None else lo}, {'inf' if hi is None else hi}]"


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

    def absorb(file: Path, data: dict[str, Any]) -> None:
        nonlocal lcm_url, host_buses
        ck = _Checker(file)
        if file in stack:
            chain = " -> ".join(p.name for p in [*stack, file])
            raise ck.fail("include", f"files include each other in a cycle: {chain}")
        if file in seen:  # included twice along different paths: once is enough
            return
        seen.append(file)
        stack.append(file)
        ck.known_keys(data, "", PROFILE_KEYS)
        includes = data.get("include", [])
        if not isinstance(includes, list) or not all(isinstance(x, str) for x in includes):
            raise ck.fail("include", f"must be a list of file names, got {includes!r}")
        for inc in includes:
            inc_path = (file.parent / inc).resolve()
            if not inc_path.exists():
                raise ck.fail(
                    "include",
                    f"included file {inc!r} does not exist",
                    allowed=", ".join(sorted(p.name for p in file.parent.glob("*.yaml"))),
                )
            absorb(inc_path, load_yaml(inc_path))
        if "overrides" in data:
            for pname, value in ck.mapping(data["overrides"] or {}, "overrides").items():
                all_overrides.append((str(pname), ck.mapping(value, f"overrides.{pname}"), file))
        if "lcm" in data:
            lcm = ck.mapping(data["lcm"], "lcm")
            ck.known_keys(lcm, "lcm", {"url", "host_buses"})
            if "url" in lcm:
                url = ck.string(lcm, "lcm", "url")
                if not (url.startswith("udpm://") or url.startswith("memq://")):
                    raise ck.fail(
                        "lcm.url",
                        f"{url!r} is not an LCM URL",
                        allowed="udpm://GROUP:PORT (or memq:// for one process)",
                    )
                lcm_url = (url, file)
            if "host_buses" in lcm:
                host_buses = (ck.string(lcm, "lcm", "host_buses", choices=HOST_BUSES), file)
        for section in sections:
            if section in data:
                entries = ck.mapping(data[section], section)
                for name, value in entries.items():
                    sections[section][str(name)] = (value, file)
        stack.pop()

    data = load_yaml(path)
    absorb(path, data)
    ck = _Checker(path)
    name = ck.string(data, "", "profile", default=path.stem)
    mode = ck.string(data, "", "mode", default="realtime", choices=MODES)
    report_hz = ck.number(data, "", "timing_report_hz", default=10.0, lo=0.1, hi=100.0)
    rtf = ck.number(data, "", "rtf", default=1.0, lo=0.01, hi=1.0)
    if rtf != 1.0 and mode != "realtime":
        raise ck.fail("rtf", f"a real-time factor of {rtf:g} needs mode: realtime",
                      allowed="1.0 in lockstep")
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
        hc = _Checker(file)
        h = hc.mapping(value, f"hosts.{hname}")
        hc.known_keys(h, f"hosts.{hname}",
                      {"address", "description", "lcm_port_offset", "cpus", "deputy"})
        cpus = h.get("cpus")
        if cpus is not None and (
            not isinstance(cpus, list) or not cpus
            or not all(isinstance(x, int) and not isinstance(x, bool) and x >= 0 for x in cpus)
        ):
            raise hc.fail(f"hosts.{hname}.cpus", f"must be a list of CPU numbers, got {cpus!r}",
                          allowed=f"CPU numbers 0..{(os.cpu_count() or 1) - 1} on this machine")
        hosts[hname] = HostConfig(
            hname,
            hc.string(h, f"hosts.{hname}", "address"),
            str(h.get("description", "")),
            # (below the instance step: a host's port must not be the next instance's)
            hc.number(h, f"hosts.{hname}", "lcm_port_offset", default=0, lo=0,
                      hi=INSTANCE_PORT_STEP - 1, integer=True),
            tuple(cpus) if cpus else None,
            hc.boolean(h, f"hosts.{hname}", "deputy", default=False),
        )

    channels = {
        cname: _channel(cname, value, file, hosts)
        for cname, (value, file) in sections["channels"].items()
    }
    for cname, (_, file) in sections["channels"].items():
        scope = channels[cname].scope
        if scope and scope != NETWORK and scope not in hosts:
            raise _Checker(file).fail(f"channels.{cname}.scope", f"unknown scope {scope!r}",
                                      allowed=", ".join(["network", "host", *sorted(hosts)]))

    for pname, _, ofile in all_overrides:
        if pname not in sections["processes"]:
            raise _Checker(ofile).fail(
                f"overrides.{pname}",
                "no such process",
                allowed=", ".join(sorted(sections["processes"])),
            )
    processes = {}
    for pname, (value, file) in sections["processes"].items():
        raw = _Checker(file).mapping(value, f"processes.{pname}")
        mine = [(ov, ofile) for name, ov, ofile in all_overrides if name == pname]
        for ov, _ in mine:
            raw = _merge(raw, ov)
        try:
            processes[pname] = _process(pname, raw, file, hosts, channels, hw_dir)
        except ConfigError as exc:
            raise _blame_override(exc, pname, mine) from None

    launch = data.get("launch")
    if not isinstance(launch, list) or not launch or not all(isinstance(x, str) for x in launch):
        raise ck.fail(
            "launch",
            f"must be a non-empty list of process names, got {launch!r}",
            allowed=", ".join(sorted(processes)),
        )
    for i, pname in enumerate(launch):
        if pname not in processes:
            raise ck.fail(
                f"launch[{i}]", f"no process named {pname!r}", allowed=", ".join(sorted(processes))
            )
    for pname in launch:
        for dep in processes[pname].depends_on:
            if dep not in launch:
                raise ck.fail(
                    "launch",
                    f"{pname} depends on {dep}, which this profile does not launch",
                    allowed=", ".join(sorted(processes)),
                )
    domains, channel_domains = _domains(url, host_buses, hosts, channels, processes, launch)
    sup = ck.mapping(data.get("supervisor") or {}, "supervisor")
    ck.known_keys(sup, "supervisor",
                  {"status_channel", "orders_channel", "timing_channel", "host",
                   "deputy_orders_channel", "deputy_status_channel"})
    sup_host = ck.string(sup, "supervisor", "host", default="laptop" if "laptop" in hosts else "",
                         choices=tuple(sorted(hosts)) or None) if hosts else ""
    # Relative paths in params (terrains, ...) resolve against hw_config/ when the profile builds
    # on the product configuration, else against the profile's own folder.
    if any(HW_CONFIG_DIR.resolve() in f.parents for f in seen):
        hw_dir = HW_CONFIG_DIR.resolve()
    return Profile(
        name=name,
        path=path,
        hw_config_dir=hw_dir,
        mode=mode,
        lcm_url=url,
        base_lcm_url=base_url,
        hosts=hosts,
        channels=channels,
        processes=processes,
        launch=tuple(launch),
        timing_report_hz=report_hz,
        status_channel=ck.string(sup, "supervisor", "status_channel", default="SUPERVISOR_STATUS"),
        orders_channel=ck.string(sup, "supervisor", "orders_channel", default="SUPERVISOR_ORDERS"),
        timing_channel=ck.string(sup, "supervisor", "timing_channel", default="TIMING"),
        deputy_orders_channel=ck.string(sup, "supervisor", "deputy_orders_channel",
                                        default="DEPUTY_ORDERS"),
        deputy_status_channel=ck.string(sup, "supervisor", "deputy_status_channel",
                                        default="DEPUTY_STATUS"),
        domains=domains,
        channel_domains=channel_domains,
        rtf=rtf,
        supervisor_host=sup_host,
    )


def _domains(
    url: str,
    host_buses: tuple[str, Path],
    hosts: dict[str, HostConfig],
    channels: dict[str, ChannelConfig],
    processes: dict[str, ProcessConfig],
    launch: list[str],
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
                raise ConfigError(
                    str(proc.source_file), proc.key("inputs", role),
                    f"{ch.name} stays on host {domain} (ttl 0), but {proc.name} runs on "
                    f"{proc.host} and would never receive it",
                    allowed="a channel that crosses hosts (NETWORK_ name or `scope: network` "
                    "in channels.yaml), or run the process on " + domain,
                )
    return domains, out


def _blame_override(
    exc: ConfigError, pname: str, overrides: list[tuple[dict[str, Any], Path]]
) -> ConfigError:
    """Point an error at the ``overrides`` entry that set the value, when one did."""
    prefix = f"processes.{pname}."
    if not exc.key.startswith(prefix):
        return exc
    rest = exc.key[len(prefix) :]
    for override, ofile in reversed(overrides):
        node: Any = override
        for part in rest.split("."):
            if not isinstance(node, dict) or part not in node:
                break
            node = node[part]
        else:
            return ConfigError(str(ofile), f"overrides.{pname}.{rest}", exc.problem, exc.allowed)
    return exc


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
    ck = _Checker(file)
    key = f"channels.{cname}"
    if isinstance(value, str):
        if not value.replace("_", "").isalnum():
            raise ck.fail(
                key,
                f"{value!r} is not a valid LCM channel name",
                allowed="letters, digits and underscores",
            )
        return ChannelConfig(cname, value)
    d = ck.mapping(value, key)
    ck.known_keys(d, key, {"udp", "name", "scope"})
    if "udp" in d:
        addr = ck.string(d, key, "udp")
        host, _, port_s = addr.rpartition(":")
        if not host or not port_s.isdigit() or not 0 < int(port_s) < 65536:
            raise ck.fail(
                f"{key}.udp", f"{addr!r} is not HOST:PORT", allowed="e.g. 127.0.0.1:25000"
            )
        port = int(port_s) + INSTANCE_PORT_STEP * instance()
        if hosts and host in hosts:
            host = hosts[host].address
        elif hosts is not None and not _is_ip(host):
            raise ck.fail(f"{key}.udp", f"{host!r} is neither a host of hosts.yaml nor an IPv4 "
                          "address", allowed=", ".join(sorted(hosts or {})) + " or a.b.c.d")
        return ChannelConfig(cname, f"udp:{host}:{port}", udp=(host, port))
    name = ck.string(d, key, "name")
    if not name.replace("_", "").isalnum():
        raise ck.fail(f"{key}.name", f"{name!r} is not a valid LCM channel name",
                      allowed="letters, digits and underscores")
    scope = ck.string(d, key, "scope", default="")
    if scope == "host":
        scope = ""
    return ChannelConfig(cname, name, scope=scope)


def _process(
    pname: str,
    d: dict[str, Any],
    file: Path,
    hosts: dict[str, HostConfig],
    channels: dict[str, ChannelConfig],
    hw_dir: Path,
) -> ProcessConfig:
    ck = _Checker(file)
    key = f"processes.{pname}"
    ck.known_keys(d, key, PROCESS_KEYS)
    host = ck.string(d, key, "host", choices=tuple(sorted(hosts)) or None)
    module = ck.string(d, key, "module")
    if importlib.util.find_spec(module.split(".")[0]) is None:
        raise ck.fail(f"{key}.module", f"no importable Python package for {module!r}")
    rate = ck.number(d, key, "rate_hz", default=None, lo=0.0, hi=100000.0, lo_open=True)
    deadline = ck.number(d, key, "deadline_ms", default=None, lo=0.0, hi=60000.0, lo_open=True)

    def ports(section: str) -> dict[str, ChannelConfig]:
        table = ck.mapping(d.get(section) or {}, f"{key}.{section}")
        out = {}
        for role, cname in table.items():
            if cname not in channels:
                raise ck.fail(
                    f"{key}.{section}.{role}",
                    f"unknown channel {cname!r}",
                    allowed=", ".join(sorted(channels)),
                )
            out[str(role)] = channels[cname]
        return out

    inputs, outputs = ports("inputs"), ports("outputs")
    for section, table in (("inputs", inputs), ("outputs", outputs)):
        roles: dict[str, str] = {}
        for role, ch in table.items():  # two roles on one channel: one stream taken as two
            if ch.name in roles:
                raise ck.fail(f"{key}.{section}.{role}",
                              f"channel {ch.name} is already its {section[:-1]} "
                              f"{roles[ch.name]!r}", allowed="one role per channel")
            roles[ch.name] = role
    deps = d.get("depends_on") or []
    if not isinstance(deps, list) or not all(isinstance(x, str) for x in deps):
        raise ck.fail(f"{key}.depends_on", f"must be a list of process names, got {deps!r}")
    ready = ck.mapping(d.get("ready") or {}, f"{key}.ready")
    ck.known_keys(ready, f"{key}.ready", {"timeout_s"})
    ready_timeout = ck.number(
        ready, f"{key}.ready", "timeout_s", default=15.0, lo=0.0, lo_open=True
    )
    max_rate = ck.number(d, key, "max_rate_hz", default=None, lo=0.0, hi=100000.0, lo_open=True)
    out_rates = ck.mapping(d.get("output_rate_hz") or {}, f"{key}.output_rate_hz")
    for role in out_rates:
        if role not in outputs:
            raise ck.fail(f"{key}.output_rate_hz.{role}", "not an output of this process",
                          allowed=", ".join(sorted(outputs)))
        ck.number(out_rates, f"{key}.output_rate_hz", role, lo=0.0, hi=100000.0, lo_open=True)
    r = ck.mapping(d.get("restart") or {}, f"{key}.restart")
    ck.known_keys(r, f"{key}.restart", RESTART_KEYS)
    restart = RestartPolicy(
        policy=ck.string(
            r, f"{key}.restart", "policy", default="on-failure", choices=RESTART_POLICIES
        ),
        max_restarts=ck.number(
            r, f"{key}.restart", "max_restarts", default=5, lo=0, hi=1000, integer=True
        ),
        window_s=ck.number(r, f"{key}.restart", "window_s", default=60.0, lo=0.0, lo_open=True),
        backoff_initial_s=ck.number(r, f"{key}.restart", "backoff_initial_s", default=0.5, lo=0.0),
        backoff_max_s=ck.number(r, f"{key}.restart", "backoff_max_s", default=8.0, lo=0.0),
        standby=ck.boolean(r, f"{key}.restart", "standby", False),
    )
    aff = d.get("cpu_affinity")
    if aff is not None and (
        not isinstance(aff, list)
        or not aff
        or not all(isinstance(x, int) and not isinstance(x, bool) and x >= 0 for x in aff)
    ):
        raise ck.fail(
            f"{key}.cpu_affinity",
            f"must be a list of CPU numbers, got {aff!r}",
            allowed=f"CPU numbers 0..{(os.cpu_count() or 1) - 1}",
        )
    nice = ck.number(d, key, "nice", default=None, lo=-20, hi=19, integer=True)
    rt_priority = ck.number(d, key, "rt_priority", default=None, lo=1, hi=99, integer=True)
    gains = d.get("gains")
    gains_file = None
    if gains is not None:
        gains_file = (file.parent / ck.string(d, key, "gains")).resolve()
        if not gains_file.exists():
            raise ck.fail(
                f"{key}.gains",
                f"gains file {gains!r} does not exist",
                allowed="a path relative to hw_config/, e.g. gains/osc.yaml",
            )
    params = ck.mapping(d.get("params") or {}, f"{key}.params")
    limits: dict[str, dict[str, tuple[float, float]]] = {}
    for role, fields in ck.mapping(d.get("limits") or {}, f"{key}.limits").items():
        if role not in inputs:
            raise ck.fail(f"{key}.limits.{role}", "not an input of this process",
                          allowed=", ".join(sorted(inputs)))
        limits[str(role)] = {}
        for fname, rng in ck.mapping(fields or {}, f"{key}.limits.{role}").items():
            if fname == "utime_step_s":  # the stream's clock (runtime.validate): one number
                if isinstance(rng, bool) or not isinstance(rng, int | float) or not rng > 0:
                    raise ck.fail(f"{key}.limits.{role}.utime_step_s",
                                  f"must be seconds > 0, got {rng!r}")
                limits[str(role)][fname] = (0.0, float(rng))
                continue
            ok = (isinstance(rng, list) and len(rng) == 2
                  and all(isinstance(x, int | float) and not isinstance(x, bool) for x in rng)
                  and all(x == x for x in rng) and rng[0] <= rng[1])
            if not ok:
                raise ck.fail(f"{key}.limits.{role}.{fname}", f"must be [lo, hi], got {rng!r}",
                              allowed="two numbers, lo <= hi")
            limits[str(role)][str(fname)] = (float(rng[0]), float(rng[1]))
    return ProcessConfig(
        name=pname,
        host=host,
        module=module,
        source_file=file,
        description=str(d.get("description", "")),
        rate_hz=rate,
        deadline_ms=deadline,
        inputs=inputs,
        outputs=outputs,
        depends_on=tuple(deps),
        ready_timeout_s=ready_timeout,
        restart=restart,
        required=ck.boolean(d, key, "required", True),
        cpu_affinity=tuple(aff) if aff else (hosts[host].cpus if host in hosts else None),
        nice=nice,
        rt_priority=rt_priority,
        max_rate_hz=max_rate,
        output_rate_hz={str(k): float(v) for k, v in out_rates.items()},
        gc=ck.string(d, key, "gc", default="freeze", choices=("on", "freeze")),
        params=params,
        limits=limits,
        gains_file=gains_file,
        harness_delay_ms=ck.number(d, key, "harness_delay_ms", default=0.0, lo=0.0, hi=1000.0),
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
            raise ConfigError(
                str(proc.source_file),
                proc.key("depends_on"),
                "dependency cycle: " + " -> ".join([*chain, name]),
            )
        state[name] = 1
        proc = profile.processes[name]
        for dep in proc.depends_on:
            if dep not in profile.processes:
                raise ConfigError(
                    str(proc.source_file),
                    proc.key("depends_on"),
                    f"no process named {dep!r}",
                    allowed=", ".join(sorted(profile.processes)),
                )
            visit(dep, [*chain, name])
        state[name] = 2
        order.append(name)

    for name in profile.launch:
        visit(name, [])
    return order
