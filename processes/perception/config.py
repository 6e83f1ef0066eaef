"""Load frozen parameter dataclasses from profiled hw_config YAML files, with checked values.

Each field of a parameter dataclass declares its bounds in `field(metadata=...)`: `min`, `max`
(inclusive unless `min_open`/`max_open`), or `choices`. A file holds `default_profile` and a
`profiles` mapping (Table VIII has a hardware and a simulation column); every bad value raises
`runtime.errors.ConfigError(file, key, problem, allowed)` naming the dotted key.
"""

from __future__ import annotations

import dataclasses
import math
import os
from pathlib import Path
from typing import Any, TypeVar

import yaml

from runtime.config import safe_load
from runtime.errors import ConfigError

T = TypeVar("T")


def bounded(default: Any, *, lo: float | None = None, hi: float | None = None,
            lo_open: bool = False, hi_open: bool = False,
            choices: tuple[str, ...] | None = None, unit: str = "") -> Any:
    """A dataclass field with a default and the range `load_params` enforces."""
    meta = {"min": lo, "max": hi, "min_open": lo_open, "max_open": hi_open,
            "choices": choices, "unit": unit}
    return dataclasses.field(default=default, metadata=meta)


def _allowed_text(meta: dataclasses.Field[Any] | Any) -> str:
    m = meta.metadata
    if m.get("choices"):
        return ", ".join(m["choices"])
    lo, hi = m.get("min"), m.get("max")
    lb = "(" if m.get("min_open") else "["
    rb = ")" if m.get("max_open") else "]"
    lo_s = "-inf" if lo is None else f"{lo:g}"
    hi_s = "inf" if hi is None else f"{hi:g}"
    unit = f" {m['unit']}" if m.get("unit") else ""
    return f"{lb}{lo_s}, {hi_s}{rb}{unit}"


def _check_value(file: str, key: str, f: dataclasses.Field[Any], value: Any) -> Any:
    """Coerce `value` to the field's default type and check its bounds, or raise ConfigError."""
    default = f.default
    allowed = _allowed_text(f)
    if isinstance(default, bool):
        if not isinstance(value, bool):
            raise ConfigError(file, key, f"expected true or false, got {value!r}", "true, false")
        return value
    if isinstance(default, str):
        if not isinstance(value, str):
            raise ConfigError(file, key, f"expected a string, got {value!r}", allowed)
        choices = f.metadata.get("choices")
        if choices and value not in choices:
            raise ConfigError(file, key, f"unknown value {value!r}", allowed)
        return value
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ConfigError(file, key, f"expected a number, got {value!r}", allowed)
    if isinstance(default, int) and not isinstance(value, int):
        if float(value).is_integer():
            value = int(value)
        else:
            raise ConfigError(file, key, f"expected an integer, got {value!r}", allowed)
    num = float(value)
    if not math.isfinite(num):
        raise ConfigError(file, key, f"must be finite, got {value!r}", allowed)
    lo, hi = f.metadata.get("min"), f.metadata.get("max")
    if lo is not None and (num < lo or (f.metadata.get("min_open") and num == lo)):
        raise ConfigError(file, key, f"{value!r} is out of range", allowed)
    if hi is not None and (num > hi or (f.metadata.get("max_open") and num == hi)):
        raise ConfigError(file, key, f"{value!r} is out of range", allowed)
    return int(value) if isinstance(default, int) else float(value)


def load_params(cls: type[T], path: str | os.PathLike[str], profile: str | None = None) -> T:
    """Build `cls` from `profiles.<profile>` of the YAML file `path` (default: `default_profile`).

    Missing keys keep the dataclass default; unknown keys and bad values raise ConfigError.
    """
    file = str(path)
    try:
        raw = safe_load(Path(path).read_text(encoding="utf-8"))
    except OSError as exc:
        raise ConfigError(file, "<file>", f"cannot read: {exc.strerror}") from exc
    except yaml.YAMLError as exc:
        raise ConfigError(file, "<file>", f"not valid YAML: {exc}") from exc
    if not isinstance(raw, dict) or not isinstance(raw.get("profiles"), dict):
        raise ConfigError(file, "profiles", "missing or not a mapping of profile name -> values")
    profiles = raw["profiles"]
    name = profile if profile is not None else raw.get("default_profile")
    if name not in profiles:
        raise ConfigError(file, "default_profile" if profile is None else "profiles",
                          f"unknown profile {name!r}", ", ".join(map(str, profiles)))
    values = profiles[name] or {}
    if not isinstance(values, dict):
        raise ConfigError(file, f"profiles.{name}", "must be a mapping of key -> value")
    fields = {f.name: f for f in dataclasses.fields(cls)}  # type: ignore[arg-type]
    kwargs: dict[str, Any] = {}
    for key, value in values.items():
        dotted = f"profiles.{name}.{key}"
        if key not in fields:
            raise ConfigError(file, dotted, "unknown key", ", ".join(sorted(fields)))
        kwargs[key] = _check_value(file, dotted, fields[key], value)
    return cls(**kwargs)


def validate(obj: Any, file: str = "<params>") -> None:
    """Check every field of a constructed parameter dataclass against its bounds."""
    for f in dataclasses.fields(obj):
        _check_value(file, f.name, f, getattr(obj, f.name))
