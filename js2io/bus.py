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
