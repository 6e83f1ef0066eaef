"""Edge validation: every input message a node takes in is checked before the node sees it.

One place for it (issue: a single malformed or poisoned message must never reach an
algorithm): the port buffers of both runners (``runtime.loops`` live, ``runtime.harness``
deterministic) run an ``InputCheck`` on each decoded message; a message that fails is
dropped and counted, and the node keeps the previous good one. A check has three parts:

* every floating-point field, at any depth (nested structs, arrays of them), is finite;
* the ranges a process declares for its inputs in ``hw_config`` (``limits:`` in
  processes.yaml: role -> field -> [lo, hi], applied to every element of an array);
* the consistency of a message type's own fields (``CONSISTENCY``: an elevation map's
  byte count matches its grid; the checks are its codec's, ``runtime.codecs``), which no
  range can express;
* with ``utime_step_s`` in the role's limits, the stream's time: ``header.utime`` neither
  goes back nor jumps ahead by more than that from the last admitted message. One message
  off the stream's clock (a bit flip, a stale replay) is rejected; a real jump (a sim
  restart, a long stall) costs one message: the next that agrees with it re-syncs.

The checks are built once per port from the lcm-gen type's ``__slots__``/``__typenames__``
(no per-message introspection): a robot state costs ~3 us.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import Any

from lcmtypes import elevation_map_t, foothold_set_t, guide_plan_t

from .codecs import elevation_map_problem, foothold_set_problem, guide_plan_problem
from .errors import ConfigError

_FLOATS = ("double", "float")
_NUMBERS = (*_FLOATS, "int8_t", "int16_t", "int32_t", "int64_t", "byte")

Reason = str | None

#: per message type: what its fields must satisfy together
CONSISTENCY: dict[type, Callable[[Any], Reason]] = {
    elevation_map_t: elevation_map_problem,
    foothold_set_t: foothold_set_problem,
    guide_plan_t: guide_plan_problem,
}


def _finite_checker(msg_type: type) -> Callable[[Any], Reason] | None:
    """A function naming the first non-finite float field of a ``msg_type`` message (None:
    the type has no float field at any depth)."""
    import importlib

    parts: list[Callable[[Any], Reason]] = []
    for name, tname, dims in zip(msg_type.__slots__, msg_type.__typenames__,  # type: ignore[attr-defined]
                                 msg_type.__dimensions__, strict=True):  # type: ignore[attr-defined]
        depth = len(dims) if dims else 0
        if tname in _FLOATS:
            parts.append(_float_field(name, depth))
        elif "." in tname:  # a nested lcm type
            mod, cls = tname.rsplit(".", 1)
            sub = getattr(importlib.import_module(f"{mod}.{cls}"), cls)
            inner = _finite_checker(sub)
            if inner is not None:
                parts.append(_struct_field(name, depth, inner))
    if not parts:
        return None

    def check(msg: Any) -> Reason:
        for p in parts:
            why = p(msg)
            if why is not None:
                return why
        return None

    return check


def _float_field(name: str, depth: int) -> Callable[[Any], Reason]:
    isfinite = math.isfinite
    if depth == 0:
        return lambda m: None if isfinite(getattr(m, name)) else f"{name} is not finite"
    if depth == 1:  # the sum of finite values is finite (unless ~1e308: rejected too)
        return lambda m: None if isfinite(sum(getattr(m, name))) else f"{name} is not finite"

    def nested(m: Any) -> Reason:
        for row in getattr(m, name):
            if not isfinite(sum(row)):
                return f"{name} is not finite"
        return None

    return nested


def _struct_field(name: str, depth: int, inner: Callable[[Any], Reason]
                  ) -> Callable[[Any], Reason]:
    def check(m: Any) -> Reason:
        v = getattr(m, name)
        for item in (v if depth else (v,)):
            why = inner(item)
            if why is not None:
                return f"{name}: {why}"
        return None

    return check


class InputCheck:
    """Whether one decoded message may reach the node: ``check(msg)`` is None, or the reason
    it may not. Built once per input port."""

    def __init__(self, msg_type: type, ranges: Mapping[str, Any] | None = None,
                 source: str = "<limits>", key: str = "limits") -> None:
        self.msg_type = msg_type
        self._finite = _finite_checker(msg_type)
        self._consistent = CONSISTENCY.get(msg_type)
        ranges = dict(ranges or {})
        step = ranges.pop("utime_step_s", None)
        if step is not None:
            if "header" not in msg_type.__slots__:  # type: ignore[attr-defined]
                raise ConfigError(source, f"{key}.utime_step_s",
                                  f"{msg_type.__name__} has no header to time")
            hi = float(step[1])  # a range (0, hi) as the other limits: the step allowed is hi
            if not hi > 0.0:
                raise ConfigError(source, f"{key}.utime_step_s", f"{step!r} is not > 0 s")
        self._max_step_us = None if step is None else round(hi * 1e6)
        self._last_utime: int | None = None
        self._candidate: int | None = None
        fields = dict(zip(msg_type.__slots__, zip(msg_type.__typenames__,  # type: ignore[attr-defined]
                                                  msg_type.__dimensions__, strict=True),  # type: ignore[attr-defined]
                          strict=True))
        self._ranges: list[tuple[str, float, float, bool]] = []
        for name, (lo, hi) in ranges.items():
            if name not in fields or fields[name][0] not in _NUMBERS:
                numeric = sorted(f for f, (t, _) in fields.items() if t in _NUMBERS)
                raise ConfigError(source, f"{key}.{name}",
                                  f"{msg_type.__name__} has no numeric field {name!r}",
                                  allowed=", ".join(numeric))
            dims = fields[name][1]
            if dims and len(dims) > 1:
                raise ConfigError(source, f"{key}.{name}",
                                  "ranges apply to scalars and 1-D arrays only")
            self._ranges.append((name, float(lo), float(hi), bool(dims)))

    def __call__(self, msg: Any) -> Reason:
        if self._finite is not None:
            why = self._finite(msg)
            if why is not None:
                return why
        for name, lo, hi, array in self._ranges:
            v = getattr(msg, name)
            if array:
                if v and not (lo <= min(v) and max(v) <= hi):
                    return f"{name} outside [{lo:g}, {hi:g}] ({min(v):g} .. {max(v):g})"
            elif not lo <= v <= hi:
                return f"{name} = {v:g} outside [{lo:g}, {hi:g}]"
        if self._consistent is not None:
            why = self._consistent(msg)
            if why is not None:
                return why
        if self._max_step_us is not None:
            return self._on_clock(int(msg.header.utime))
        return None

    def _on_clock(self, u: int) -> Reason:
        """``utime_step_s``: admit ``u`` if it follows the last admitted time, or confirms a
        jump the previous rejected message made (then the stream re-syncs to it)."""
        last, step = self._last_utime, self._max_step_us
        assert step is not None
        if last is None or 0 <= u - last <= step:
            self._last_utime, self._candidate = u, None
            return None
        cand = self._candidate
        if cand is not None and 0 <= u - cand <= step:
            self._last_utime, self._candidate = u, None  # a real jump: two agree on it
            return None
        self._candidate = u
        return (f"header.utime {u} is {(u - last) * 1e-6:+.3f} s from the stream's "
                f"({last}): off its clock (allowed 0 .. {step * 1e-6:g} s)")


def input_checks(inputs: Mapping[str, type], limits: Mapping[str, Mapping[str, Any]],
                 source: str = "", key: str = "limits", own: tuple[str, ...] = ()
                 ) -> dict[str, InputCheck]:
    """One ``InputCheck`` per LCM input role (raw-bytes roles, and the ``own`` ones the node
    validates itself, are left alone), with the declared ``limits`` (role -> field ->
    [lo, hi]); a limit on an unknown role or field is a ``ConfigError`` naming ``source``
    and ``key``."""
    inputs = {r: t for r, t in inputs.items() if r not in own}
    for role in limits:
        if role not in inputs or inputs[role] is bytes:
            raise ConfigError(source, f"{key}.{role}", "not an LCM input of this process",
                              allowed=", ".join(sorted(r for r, t in inputs.items()
                                                       if t is not bytes)))
    return {role: InputCheck(typ, limits.get(role), source, f"{key}.{role}")
            for role, typ in inputs.items() if typ is not bytes}
