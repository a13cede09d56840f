"""Open the python-can bus the way python-can's own tools take it: -i/--interface, -c/--channel, -b/--bitrate,
extra `--bus-arg KEY=VALUE`, or python-can's configuration file / environment (`--bus-config`)."""
from __future__ import annotations

import logging

import can

from js2spec.errors import Js2Error


def quiet_socketcand() -> None:
    """python-can's socketcand client logs a WARNING per TCP segment boundary; that alone costs ~30 % of cycles."""
    logging.getLogger("can.interfaces.socketcand").setLevel(logging.ERROR)
    logging.getLogger("can.interfaces.socketcand.socketcand").setLevel(logging.ERROR)


def _first_line(text: str) -> str:
    """python-can folds tracebacks into some messages; keep what precedes them."""
    text = text.split("Traceback (most recent call last)")[0].strip()
    return text.splitlines()[0] if text else ""


class _OneLine(logging.Formatter):
    """Library warnings as one line each (no tracebacks on the console; the log file records what matters)."""

    def format(self, record):
        msg = _first_line(record.getMessage())
        return f"{self.prog}: {record.levelname.lower()}: {record.name}: {msg}"

    def formatException(self, ei):   # noqa: N802 - logging API
        return ""


def console_logging(prog: str, level=logging.WARNING) -> None:
    h = logging.StreamHandler()
    f = _OneLine()
    f.prog = prog
    h.setFormatter(f)
    root = logging.getLogger()
    root.handlers[:] = [h]
    root.setLevel(level)
    quiet_socketcand()
    import threading

    def hook(args):   # a dying library thread (e.g. python-can's notifier on a lost connection): one line
        logging.getLogger(prog).warning("thread %s stopped: %s: %s", args.thread.name if args.thread else "?",
                                        args.exc_type.__name__, _first_line(str(args.exc_value)))
    threading.excepthook = hook


def _value(v: str):
    low = v.lower()
    if low in ("true", "yes", "on"):
        return True
    if low in ("false", "no", "off"):
        return False
    for conv in (int, float):
        try:
            return conv(v)
        except ValueError:
            pass
    return v


def bus_kwargs(interface=None, channel=None, bitrate=None, bus_args=()) -> dict:
    kw: dict = {}
    if interface:
        kw["interface"] = interface
    if channel is not None:
        kw["channel"] = channel
    if bitrate:
        kw["bitrate"] = int(bitrate)
    for item in bus_args or ():
        if "=" not in item:
            raise Js2Error(f"--bus-arg {item!r}: write KEY=VALUE, e.g. --bus-arg port=29536")
        k, v = item.split("=", 1)
        kw[k.strip()] = _value(v.strip())
    if kw.get("interface") == "socketcand":
        kw.setdefault("host", "127.0.0.1")
        kw.setdefault("port", 29536)
        kw.setdefault("tcp_tune", True)
        kw.setdefault("channel", "can0")
        kw.pop("bitrate", None)
    return kw


def open_bus(kw: dict | None) -> can.BusABC:
    """kw None or {} -> python-can's configuration (file / environment)."""
    quiet_socketcand()
    try:
        return can.Bus(**(kw or {}))
    except (can.CanError, ValueError, OSError, ImportError, NotImplementedError) as e:
        desc = ", ".join(f"{k}={v}" for k, v in (kw or {}).items()) or "python-can configuration"
        raise Js2Error(f"cannot open the CAN bus ({desc}): {e}. Check the interface name, channel and that the "
                       f"adapter/daemon is up (e.g. js2-sim for a simulated bus)") from None
