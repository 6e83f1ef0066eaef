"""Typed params: a node's gains and params are a frozen dataclass, read from YAML here.

One mechanism for every process: the dataclass's fields are the allowed keys (an unknown key
is always an error), their annotations the types, and ``spec(lo=, hi=, choices=)`` in a
field's metadata the range. Every error is a ``ConfigError`` naming the file, the dotted key
and what is allowed; the launch profile's files are read with it too (``runtime.config``).
Written here rather than with pydantic or msgspec: those would need a translation layer to
give errors in the project's one shape (file, key, allowed), and the types in use are few
(numbers, booleans, strings, fixed tuples, mappings, nested dataclasses, and ``Any`` for a
free-form value that its reader checks). A check across fields (min <= max, an odd kernel)
is the dataclass's ``__post_init__`` raising ``ConfigError("<ClassName>", key, problem,
allowed)``: ``read`` puts the file and the dotted key in its place, and ``check`` runs both on
an object built in code.

    @dataclass(frozen=True)
    class SwingGains:
        kp: float = spec(120.0, lo=0.0)
        mode: str = spec("ik", choices=("ik", "task"))

    gains = read(SwingGains, yaml_mapping, file="hw_config/gains/osc.yaml", key="swing")
"""

from __future__ import annotations

import dataclasses
import math
import types
import typing
from collections.abc import Mapping
from pathlib import Path
from typing import Any, TypeVar

from runtime.errors import ConfigError

T = TypeVar("T")
_MISSING = dataclasses.MISSING


def spec(default: Any = _MISSING, *, lo: float | None = None, hi: float | None = None,
         lo_open: bool = False, hi_open: bool = False, choices: tuple[Any, ...] | None = None,
         unit: str = "", default_factory: Any = _MISSING) -> Any:
    """A dataclass field with its allowed range (``lo`` <= v <= ``hi``; ``lo_open``: lo < v,
    ``hi_open``: v < hi; ``unit`` for the message) or its allowed values, checked by
    ``read``."""
    meta = {"lo": lo, "hi": hi, "lo_open": lo_open, "hi_open": hi_open, "choices": choices,
            "unit": unit}
    if default_factory is not _MISSING:
        return dataclasses.field(default_factory=default_factory, metadata=meta)
    return dataclasses.field(default=default, metadata=meta)


def load(cls: type[T], path: str | Path, variant: str | None = None) -> T:
    """A gains file as a ``cls``. The one shape of a gains file: the fields of ``cls`` at the
    top level, and optionally ``variants: {NAME: {...}}`` (e.g. the hardware and simulation
    columns of a paper's table), one of which ``variant`` (else ``default_variant``) lays
    over the top level, key by key."""
    from runtime.config import load_yaml

    file = str(path)
    data = dict(load_yaml(Path(path)))
    variants = data.pop("variants", None)
    default = data.pop("default_variant", None)
    name = variant if variant is not None else default
    if variants is None:
        if variant is not None:
            raise ConfigError(file, "variants", f"no variants, so no variant {variant!r}",
                              "a `variants:` mapping in the file, or no `variant` param")
        return read(cls, data, file)
    if not isinstance(variants, Mapping) or not all(isinstance(v, Mapping) or v is None
                                                    for v in variants.values()):
        raise ConfigError(file, "variants", "must be a mapping of name -> mapping of values")
    if name is None:
        return read(cls, data, file)
    if name not in variants:
        raise ConfigError(file, "default_variant" if variant is None else "variants",
                          f"no variant {name!r}", ", ".join(map(str, variants)))
    top = dict(variants[name] or {})
    try:
        return read(cls, _lay_over(data, top), file)
    except ConfigError as exc:  # name the key where it is written: in the variant, or above
        if exc.key.split(".")[0].split("[")[0] in top:
            raise ConfigError(file, f"variants.{name}.{exc.key}", exc.problem,
                              exc.allowed) from None
        raise


def _lay_over(base: dict[str, Any], top: dict[str, Any]) -> dict[str, Any]:
    """``top`` over ``base``: mappings merge key by key, anything else replaces."""
    out = dict(base)
    for k, v in top.items():
        out[k] = _lay_over(out[k], v) if isinstance(v, Mapping) and isinstance(
            out.get(k), Mapping) else v
    return out


def read(cls: type[T], data: Any, file: str | Path, key: str = "") -> T:
    """``data`` (a YAML mapping) as a ``cls``: every key known, every value typed and in
    range; missing keys take the field's default (a field without one is required)."""
    file = str(file)
    if not isinstance(data, Mapping):
        raise ConfigError(file, key or "<file>", f"must be a mapping, got {data!r}")
    fields = {f.name: f for f in dataclasses.fields(cls)}  # type: ignore[arg-type]
    hints = typing.get_type_hints(cls)
    for k in data:
        if k not in fields:
            raise ConfigError(file, _join(key, str(k)), "unknown key",
                              ", ".join(sorted(fields)) or "none: it takes no keys")
    values: dict[str, Any] = {}
    for name, f in fields.items():
        if not f.init:
            continue
        full = _join(key, name)
        if name not in data:
            if f.default is _MISSING and f.default_factory is _MISSING:
                raise ConfigError(file, full, "is required", _allowed(hints[name], f))
            continue
        values[name] = _value(hints[name], data[name], f, file, full)
    try:
        return cls(**values)
    except ConfigError as exc:  # a cross-field check of __post_init__: name the file here
        if exc.file and not exc.file.startswith("<"):
            raise
        raise ConfigError(file, _join(key, exc.key), exc.problem, exc.allowed) from None


def check(obj: T, file: str | Path = "") -> T:
    """``obj``, a params dataclass built in code (``dataclasses.replace``, a test), checked as
    ``read`` checks a file's values: types and ranges (``__post_init__`` has checked the rest).
    Returns ``obj``; a ConfigError names ``file`` (default ``<ClassName>``) and the key."""
    read(type(obj), dataclasses.asdict(obj), file or f"<{type(obj).__name__}>")
    return obj


def _join(key: str, name: str) -> str:
    return f"{key}.{name}" if key else name


def _allowed(tp: Any, f: dataclasses.Field[Any] | None) -> str | None:
    meta = f.metadata if f is not None else {}
    if meta.get("choices"):
        return ", ".join(map(str, meta["choices"]))
    lo, hi = meta.get("lo"), meta.get("hi")
    if lo is not None or hi is not None:
        left = "(" if meta.get("lo_open") else "["
        right = ")" if meta.get("hi_open") else "]"
        unit = f" {meta['unit']}" if meta.get("unit") else ""
        return f"{left}{'-inf' if lo is None else lo}, {'inf' if hi is None else hi}{right}{unit}"
    if tp is bool:
        return "true, false"
    if typing.get_origin(tp) is typing.Literal:
        return ", ".join(map(str, typing.get_args(tp)))
    return None


def _value(tp: Any, v: Any, f: dataclasses.Field[Any] | None, file: str, key: str) -> Any:
    """``v`` checked against the annotation ``tp`` (and the field's range)."""
    if tp is Any:  # free-form: checked by whoever reads it (a process's params, a section)
        return v
    origin, args = typing.get_origin(tp), typing.get_args(tp)
    if origin in (typing.Union, types.UnionType):  # X | None
        if v is None and type(None) in args:
            return None
        inner = [a for a in args if a is not type(None)]
        if len(inner) == 1:
            return _value(inner[0], v, f, file, key)
        raise TypeError(f"{key}: unions other than X | None are not supported")
    if origin is typing.Literal:  # of the same type too: 1 is not True, nor 0 False
        if not any(v == a and type(v) is type(a) for a in args):
            raise ConfigError(file, key, f"{v!r} is not one of the allowed values",
                              _allowed(tp, f))
        return v
    if dataclasses.is_dataclass(tp):
        return read(tp, v, file, key)  # type: ignore[arg-type]
    if origin is tuple:
        if not isinstance(v, (list, tuple)):
            raise ConfigError(file, key, f"must be a list, got {v!r}")
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(_value(args[0], x, f, file, f"{key}[{i}]") for i, x in enumerate(v))
        if len(v) != len(args):
            raise ConfigError(file, key, f"must be a list of {len(args)}, got {len(v)}: {v!r}")
        return tuple(_value(a, x, f, file, f"{key}[{i}]")
                     for i, (a, x) in enumerate(zip(args, v, strict=True)))
    if origin in (dict, Mapping):
        if not isinstance(v, Mapping):
            raise ConfigError(file, key, f"must be a mapping, got {v!r}")
        return {str(k): _value(args[1], x, f, file, f"{key}.{k}") for k, x in v.items()}
    if tp is bool:
        if not isinstance(v, bool):
            raise ConfigError(file, key, f"must be true or false, got {v!r}", "true, false")
        return v
    if tp in (int, float):
        kind = "an integer" if tp is int else "a number"
        if isinstance(v, bool) or not isinstance(v, (int, float)) or (
                tp is int and not isinstance(v, int)):
            raise ConfigError(file, key, f"must be {kind}, got {v!r}", _allowed(tp, f))
        if not math.isfinite(v) or not _in_range(v, f):
            raise ConfigError(file, key, f"out of range: {v!r}", _allowed(tp, f) or "finite")
        return tp(v)
    if tp is str:
        if not isinstance(v, str):
            raise ConfigError(file, key, f"must be a string, got {v!r}", _allowed(tp, f))
        choices = f.metadata.get("choices") if f is not None else None
        if choices and v not in choices:
            raise ConfigError(file, key, f"{v!r} is not one of the allowed values",
                              ", ".join(choices))
        return v
    raise TypeError(f"{key}: type {tp!r} is not supported by runtime.params")


def _in_range(v: float, f: dataclasses.Field[Any] | None) -> bool:
    if f is None:
        return True
    lo, hi = f.metadata.get("lo"), f.metadata.get("hi")
    if lo is not None and (v < lo or (f.metadata.get("lo_open") and v == lo)):
        return False
    return hi is None or v < hi or (v == hi and not f.metadata.get("hi_open"))
