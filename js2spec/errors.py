"""Errors that name what was wrong and where, so a CLI can print one clear line instead of a traceback."""
from __future__ import annotations

from pathlib import Path


class Js2Error(Exception):
    """Base of every js2 error meant for the user. ``str()`` is a complete, one-line message."""


class ConfigError(Js2Error):
    """A robot, drive, trial or simulator file is missing, malformed or physically impossible.

    ``ConfigError(path, key, problem)`` prints as ``"<path>: key '<key>': <problem>"``.
    """

    def __init__(self, path: str | Path | None, key: str | None, problem: str):
        self.path = str(path) if path is not None else None
        self.key = key
        self.problem = problem
        where = self.path or "<config>"
        msg = f"{where}: key '{key}': {problem}" if key else f"{where}: {problem}"
        super().__init__(msg)


class LogError(Js2Error):
    """A js2 log cannot be read as the spec requires (not MCAP, wrong version, missing channel, ...)."""

    def __init__(self, path: str | Path | None, problem: str):
        self.path = str(path) if path is not None else None
        self.problem = problem
        super().__init__(f"{self.path or '<log>'}: {problem}")
