"""Reading the text files users hand us (URDF, YAML, EDS, model files) with one-line errors.

Every config reader goes through :func:`read_text` / :func:`load_yaml`, so a missing file, a folder, a file that is
not UTF-8 text (a binary, a Latin-1 export) or one that cannot be read is named with what to do, as a
:class:`~js2spec.errors.ConfigError`, never a traceback.
"""
from __future__ import annotations

from pathlib import Path

from .errors import ConfigError, Js2Error


def read_text(path: str | Path, what: str = "file") -> str:
    """The file's text (UTF-8). `what` names the file's role in the message ('URDF', 'trials file', ...)."""
    path = Path(path)
    if path.is_dir():
        raise ConfigError(path, None, f"is a folder; give the {what} inside it")
    if not path.is_file():
        raise ConfigError(path, None, f"{what} not found")
    try:
        data = path.read_bytes()
    except OSError as e:
        raise ConfigError(path, None, f"cannot read the {what}: {e.strerror or e}") from None
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as e:
        raise ConfigError(path, None, f"is not UTF-8 text (byte 0x{data[e.start]:02X} at offset {e.start}); "
                                      f"is it the right file? Save the {what} as UTF-8") from None


def load_yaml(path: str | Path, what: str = "YAML file"):
    """The parsed YAML document of `path` (any type; callers check the shape they need)."""
    import yaml
    text = read_text(path, what)
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise ConfigError(path, None, f"is not valid YAML ({str(exc).splitlines()[0]})") from None


def check_output_folder(path: str | Path, flag: str = "-o") -> None:
    """Refuse, before any computation, an output folder that cannot be written: a file in its place, or no
    writable folder to create it in."""
    import os
    out = Path(path)
    if out.exists() and not out.is_dir():
        raise Js2Error(f"{flag} {out}: is a file; give a folder for the outputs")
    probe = out if out.is_dir() else next((p for p in out.parents if p.exists()), Path("."))
    if not probe.is_dir() or not os.access(probe, os.W_OK | os.X_OK):
        raise Js2Error(f"{flag} {out}: {probe} is not a writable folder; choose another {flag}")
