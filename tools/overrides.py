"""``key:=value`` on the command line (as ``ros2 launch``'s arguments): a variation of a
profile without a YAML file of one's own.

* ``mode:=lockstep``: a key of the profile itself (mode, launch, ...);
* ``osc.params.max_rate_hz:=500``: a process's param;
* ``osc.rate_hz:=500``: any other key of a process (cpu_affinity, nice, rt_priority...);
* ``osc.gains.swing.kp:=120``: a value in the process's gains file (the key must be there).

The values are YAML (``[0, 1]``, ``true``, ``1e-3``). They become a profile file that includes
the given one and patches it through the one mechanism a profile has for that (``overrides``,
``runtime.config``), with a copy of each gains file changed; both are written into the
launch's log folder, so the run keeps what it ran with, and everything is validated as any
profile is (and the changed processes' params and gains as their build reads them), with
errors that name the command line and the key typed there when the bad value was typed there.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

from runtime.builder import process_module, read_config
from runtime.config import load_profile, load_yaml
from runtime.config_types import writer
from runtime.errors import ConfigError

SEP = ":="


def parse(items: list[str]) -> list[tuple[list[str], Any]]:
    """``a.b.c:=v`` items as (path, value); a clear error for anything else."""
    out = []
    for item in items:
        key, sep, raw = item.partition(SEP)
        if not sep or not key or any(not part for part in key.split(".")):
            raise ConfigError("the command line", item, "not an override",
                              "KEY:=VALUE, e.g. mode:=lockstep, osc.params.max_rate_hz:=500, "
                              "osc.gains.swing.kp:=120")
        try:
            value = yaml.safe_load(raw) if raw.strip() else ""
        except yaml.YAMLError as exc:
            raise ConfigError("the command line", item, f"value is not YAML ({exc})") from exc
        out.append((key.split("."), value))
    return out


def _set_in(doc: dict[str, Any], path: list[str], value: Any, where: str, item: str) -> None:
    """Set a key that exists in the gains document (a typo must not pass silently)."""
    node: Any = doc
    for i, part in enumerate(path):
        if not isinstance(node, dict) or part not in node:
            known = ", ".join(sorted(node)) if isinstance(node, dict) else "(not a mapping)"
            raise ConfigError(where, ".".join(path[: i + 1]), f"no such gain (from {item!r})",
                              known)
        if i == len(path) - 1:
            node[part] = value
        else:
            node = node[part]


def write_overlay(profile_path: Path, items: list[str], folder: Path) -> Path:
    """The profile ``profile_path`` with the overrides applied, as a file in ``folder``."""
    base = load_profile(profile_path)
    overlay: dict[str, Any] = {"include": [str(base.path)], "profile": base.name,
                               "mode": base.mode, "launch": list(base.launch)}
    # the keys a profile takes from its own file only (the sections merge through include)
    top = load_yaml(Path(base.path))
    for key in ("description", "timing_report_hz", "rtf", "supervisor"):
        if key in top:
            overlay[key] = top[key]
    procs: dict[str, dict[str, Any]] = {}
    gains_docs: dict[str, tuple[Path, dict[str, Any]]] = {}
    parsed = parse(items)
    for path, value in parsed:
        item = f"{'.'.join(path)}{SEP}{value}"
        head = path[0]
        if head not in base.processes:
            if len(path) > 1:
                raise ConfigError("the command line", ".".join(path),
                                  f"{head!r} is no process of profile {base.name}",
                                  ", ".join(sorted(base.processes)))
            overlay[head] = value
            continue
        proc = base.processes[head]
        if len(path) == 1:
            raise ConfigError("the command line", head, "a process needs a key",
                              f"{head}.params.NAME, {head}.gains.NAME, {head}.rate_hz, ...")
        if path[1] == "gains" and len(path) > 2:
            if proc.gains_file is None:
                raise ConfigError("the command line", ".".join(path),
                                  f"process {head} has no gains file", "its params instead")
            if head not in gains_docs:
                src = Path(proc.gains_file)
                gains_docs[head] = (src, yaml.safe_load(src.read_text()) or {})
            src, doc = gains_docs[head]
            _set_in(doc, path[2:], value, str(src), item)
            # a variant that sets the key itself would win over the top level
            # (runtime.params.load): the override goes there too, whichever variant runs
            for variant in (doc.get("variants") or {}).values():
                node = variant
                for part in path[2:-1]:
                    node = node.get(part) if isinstance(node, dict) else None
                if isinstance(node, dict) and path[-1] in node:
                    node[path[-1]] = value
            continue
        entry = procs.setdefault(head, {})
        if path[1] == "params" and len(path) > 2:
            node = entry.setdefault("params", {})
            for part in path[2:-1]:
                node = node.setdefault(part, {})
            node[path[-1]] = value
        elif len(path) == 2:
            entry[path[1]] = value
        else:
            raise ConfigError("the command line", ".".join(path), "too deep for a process key",
                              f"{head}.params.NAME or {head}.gains.A.B")
    folder.mkdir(parents=True, exist_ok=True)
    copies: dict[str, str] = {}  # a gains file written here -> its process
    for head, (src, doc) in gains_docs.items():
        out = folder / "gains" / f"{head}.{src.name}"  # (two processes may share a file name)
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(f"# {src} with the command line's overrides\n"
                       + yaml.safe_dump(doc, sort_keys=False))
        procs.setdefault(head, {})["gains"] = str(out)
        copies[str(out.resolve())] = head
    if procs:
        overlay["overrides"] = procs
    out = folder / f"{base.name}.overrides.yaml"
    out.write_text("# written by `cassie launch` from the command line's key:=value\n"
                   + yaml.safe_dump(overlay, sort_keys=False))
    typed = {".".join(path): ".".join(path) for path, _ in parsed}
    try:  # every value checked now, before anything starts
        profile = load_profile(out)
        for head in procs:  # the changed processes' params and gains, as their build reads them
            proc = profile.processes[head]
            module = process_module(proc)
            if hasattr(module, "Params"):
                read_config(proc, module)
    except ConfigError as exc:
        raise _blame_the_command_line(exc, out.resolve(), copies, typed) from None
    return out


def _blame_the_command_line(exc: ConfigError, overlay: Path, copies: dict[str, str],
                            typed: dict[str, str]) -> ConfigError:
    """``exc`` naming the command line and the key typed there, when the value it is about
    was typed there (``typed``: the items' dotted keys), not the files written from them
    (``overlay`` and the gains ``copies``); else ``exc`` as it is."""
    if exc.file == str(overlay):
        key = exc.key.removeprefix("overrides.")
    elif exc.file in copies:
        inner = exc.key.split(".", 2)  # an override of a gain a variant sets went there too
        in_file = inner[2] if inner[0] == "variants" and len(inner) == 3 else exc.key
        key = f"{copies[exc.file]}.gains.{in_file}"
    else:
        return exc
    if writer(key, typed) is None:
        return exc
    return ConfigError("the command line", key, exc.problem, exc.allowed)
