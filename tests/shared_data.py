"""Generated test data (simulated sessions, identified models, recordings) made once per test run: one folder the
whole run shares, pytest-xdist's workers included, each item built by the first process that asks for it while the
others wait (an exclusive file lock per item), so that two workers never build the same session twice.

The folder is made by the process that starts the run (``tests/conftest.py``: ``pytest_configure`` sets
``JS2_TEST_SHARED``; ``pytest_unconfigure`` removes it); a process started without it (a test module run on its own,
a script) gets a private temporary folder removed at exit."""
from __future__ import annotations

import atexit
import contextlib
import fcntl
import hashlib
import os
import shutil
import tempfile
from pathlib import Path

ENV = "JS2_TEST_SHARED"
_private: dict[str, Path] = {}


def folder(name: str) -> Path:
    """The run's folder ``name`` (made on first use)."""
    root = os.environ.get(ENV)
    if root:
        path = Path(root) / name
        path.mkdir(parents=True, exist_ok=True)
        return path
    if name not in _private:
        _private[name] = Path(tempfile.mkdtemp(prefix=f"js2_{name}_"))
        atexit.register(shutil.rmtree, _private[name], ignore_errors=True)
    return _private[name]


def key(*parts) -> str:
    """A file-name key for ``parts`` that every process computes alike (``hash()`` of a str is salted per process)."""
    return hashlib.sha256(repr(parts).encode()).hexdigest()[:16]


@contextlib.contextmanager
def build_once(path: Path):
    """``with build_once(path) as build:`` -- ``build`` is True in the one process that must make ``path`` (the
    others wait on the lock, then get False). ``path`` counts as made only when the block ends without an error."""
    done = path.with_name(path.name + ".done")
    with open(path.with_name(path.name + ".lock"), "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if done.exists():
            yield False
            return
        yield True
        done.touch()
