"""Error types shared by every part of the runtime, each carrying the fix in its message."""

from __future__ import annotations

import sys
from typing import Any


class ConfigError(ValueError):
    """A bad value in a hw_config YAML file: names the file, the dotted key and what is allowed."""

    def __init__(self, file: str, key: str, problem: str, allowed: str | None = None) -> None:
        self.file = str(file)
        self.key = key
        self.problem = problem
        self.allowed = allowed
        msg = f"{self.file}: {key}: {problem}"
        if allowed:
            msg += f" (allowed: {allowed})"
        super().__init__(msg)


class MulticastRouteError(RuntimeError):
    """LCM cannot join its multicast group because this machine has no route for it."""


class BusError(RuntimeError):
    """The LCM bus could not be created or used."""


def exit_code(fn: Any) -> int:
    """``fn()``'s exit code, with the runtime's errors said on stderr in one line each (2: a
    configuration to fix, 3: the bus or its route, 130: interrupted): every command's ending."""
    try:
        return int(fn() or 0)
    except ConfigError as exc:
        print(f"config error: {exc}", file=sys.stderr)
        return 2
    except MulticastRouteError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 3
    except BusError as exc:
        print(f"bus error: {exc}", file=sys.stderr)
        return 3
    except KeyboardInterrupt:
        return 130
