"""A js2 log as a slower logger would have written it: every k-th SYNC cycle of the same drives.

A real arm is often logged far below its drives' own loop rate (a KUKA LWR's FRI at 100-200 Hz, a CANopen master
reading the drives on a 10 ms SYNC while their current and velocity loops run at kHz). ``decimate_log`` turns a
recording made at the drives' cycle into that: feedback and command messages of every ``every``-th cycle, kept as
they were read (instantaneous samples, no anti-alias filter: a SYNC read samples the drive's current, it does not
average it), every event, the attachments and the ``js2`` metadata with ``cycle_hz`` divided by ``every``.

    decimate_log("run_500hz.mcap", "run_100hz.mcap", every=5)
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .errors import LogError
from .log import LogWriter, read_log

_OWN_KEYS = ("format", "version", "robot", "cycle_hz", "source", "created")


def decimate_log(src: str | Path, dst: str | Path, every: int) -> Path:
    """Write ``src`` read every ``every``-th SYNC cycle (counted from its first feedback cycle) to ``dst``; cycle
    numbers are divided by ``every`` (so they stay consecutive), times are kept. Returns ``dst``."""
    src, dst = Path(src), Path(dst)
    if int(every) != every or every < 1:
        raise ValueError(f"decimate_log: every must be a whole number >= 1, got {every!r}")
    every = int(every)
    log = read_log(src)
    fb = log.feedback
    if len(fb) == 0:
        raise LogError(src, "holds no feedback to decimate")
    c0 = int(fb.cycle[0])
    rate = float(log.meta["cycle_hz"]) / every
    extra = {k: v for k, v in log.meta.items() if k not in _OWN_KEYS}
    extra["decimated_from"] = f"{src.name} at {log.meta['cycle_hz']} Hz, every {every}th cycle"
    with LogWriter(dst, robot=log.meta["robot"], cycle_hz=rate, source=log.meta["source"], urdf_text=log.urdf_text,
                   drives_yaml=log.drives_yaml, start_ns=0, extra_metadata=extra) as w:
        for name, data in log.attachments.items():
            if name not in ("robot.urdf", "drives.yaml"):
                w.attach(name, "application/octet-stream", data)
        for i in np.flatnonzero((fb.cycle - c0) % every == 0):
            w.feedback((int(fb.cycle[i]) - c0) // every, float(fb.t[i]), fb.motor_position[i], fb.torque[i],
                       None if fb.motor_current is None else fb.motor_current[i],
                       None if fb.status is None else fb.status[i], fb.valid[i])
        cmd = log.command
        if cmd is not None and len(cmd):
            for i in np.flatnonzero((cmd.cycle - c0) % every == 0):
                w.command((int(cmd.cycle[i]) - c0) // every, float(cmd.t[i]), cmd.mode[i], cmd.target_torque[i],
                          _row(cmd.target_velocity, i), _row(cmd.target_position, i))
        for e in log.events:
            fields = {k: v for k, v in e.items() if k not in ("t", "kind", "trial")}
            w.event(float(e["t"]), e["kind"], e["trial"], **fields)
    return dst


def _row(x: np.ndarray | None, i: int):
    """Row i of an optional command field; None where the message had none (read back as NaN)."""
    return None if x is None or np.all(np.isnan(x[i])) else x[i]
