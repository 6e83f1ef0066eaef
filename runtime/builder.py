"""Building a process's node from hw_config: the one builder every runner uses.

The live runner (``cassie run``), the deterministic harness, ``cassie check`` and the
benchmarks all make a node here, so a node is the same object whichever runs it. A process
module declares:

* ``Params``: a frozen dataclass of its ``params:`` in processes.yaml (``runtime.params``);
* ``Gains``: a frozen dataclass of its gains file (``gains:``), or None when it has none;
* ``make_node(proc, profile, params, gains) -> Node``.

The builder reads and checks both before ``make_node`` runs (unknown keys rejected, every
error naming the file, the key and what is allowed); a gains file with ``variants`` is read
in the variant named by the params' ``variant`` field, if it has one. A module not moved to
this contract yet keeps ``make_node(proc, profile)``, which checks its own inputs.
"""

from __future__ import annotations

import importlib
from typing import Any

from runtime.config_types import ProcessConfig, Profile
from runtime.errors import ConfigError
from runtime.node import Node
from runtime.params import load, read


def process_module(proc: ProcessConfig) -> Any:
    """The module ``proc`` runs (its ``module:`` in processes.yaml)."""
    return importlib.import_module(proc.module)


def read_config(proc: ProcessConfig, module: Any) -> tuple[Any, Any]:
    """(params, gains) of ``proc`` as its module's ``Params`` and ``Gains``; an error in a
    param a profile's ``overrides:`` wrote names that profile (``ProcessConfig.blame``)."""
    try:
        params = read(module.Params, proc.params, proc.source_file, key=proc.key("params"))
    except ConfigError as exc:
        raise proc.blame(exc) from None
    gains_cls = getattr(module, "Gains", None)
    if gains_cls is None:
        if proc.gains_file:
            raise ConfigError(str(proc.source_file), proc.key("gains"),
                              f"{proc.module} takes no gains file", "no `gains:` key")
        return params, None
    if not proc.gains_file:
        raise ConfigError(str(proc.source_file), proc.key("gains"), "is required",
                          f"a gains file for {proc.module} (hw_config/gains/*.yaml)")
    return params, load(gains_cls, proc.gains_file, getattr(params, "variant", None))


def apply_rates(node: Node, proc: ProcessConfig) -> None:
    """A node's period and deadline from hw_config, the same for both runners: a periodic
    node ticks every 1 / ``rate_hz``; the deadline is ``deadline_ms``, else the period."""
    if node.period_s is None and node.trigger_role is None and proc.rate_hz:
        node.period_s = 1.0 / proc.rate_hz
    if node.deadline_s is None:
        if proc.deadline_ms is not None:
            node.deadline_s = proc.deadline_ms / 1000.0
        elif node.period_s:
            node.deadline_s = node.period_s


def build_node(proc: ProcessConfig, profile: Profile, module: Any = None) -> Node:
    """``proc``'s node, its params and gains checked first; a ConfigError names the file.
    ``module``: build with this module instead of ``proc.module`` (a benchmark's copy of
    another revision's). An error about a value a profile's ``overrides:`` wrote names that
    profile and the override's key."""
    module = process_module(proc) if module is None else module
    if not hasattr(module, "make_node"):
        raise ConfigError(str(proc.source_file), proc.key("module"),
                          f"{proc.module} has no make_node and runs no node",
                          "a module with make_node(proc, profile, params, gains)")
    try:
        if hasattr(module, "Params"):
            params, gains = read_config(proc, module)
            return module.make_node(proc, profile, params, gains)
        return module.make_node(proc, profile)
    except ConfigError as exc:  # (make_node's own checks of its params too)
        raise proc.blame(exc) from None
