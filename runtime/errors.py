"""Error types shared by every part of the runtime, each carrying the fix in its message."""

from __future__ import annotations


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
