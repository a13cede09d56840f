"""Plain recordings (CSV or NumPy arrays of time, positions, torques or currents) + URDF + drives file -> js2 log.

The log is written through ``js2spec.log.LogWriter`` with source ``import:<what>``, so any arm's recording can be
identified by ``js2-identify`` like our own logs. Samples go on the cycle grid ``cycle = round((t - t0) * rate)``;
duplicated cycles are dropped (first kept) and missing ones stay missing (the reader sees them as lost cycles: no
silent resampling). Positions are motor-side angles in the log: joint-side recordings are converted with
``theta_m = K^-1 (theta - offset)``. With ``torque_side: motor`` a log needs currents: given only torques, the current
is ``torque / torque_constant`` (and vice versa).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from js2spec.drives import load_drives
from js2spec.errors import ConfigError, Js2Error
from js2spec.log import LogWriter


class ImportError_(Js2Error):
    """A recording cannot be imported (missing columns, shapes that disagree, NaNs); names the file."""


@dataclass
class Recording:
    t: np.ndarray                     # (N,) s
    position: np.ndarray              # (N, n) rad
    torque: np.ndarray | None         # (N, n) N m (side: drives.torque_side)
    current: np.ndarray | None = None  # (N, n) A
    source: str = ""
    extra: dict = field(default_factory=dict)


def _read_table(path: Path, n: int | None = None, columns=None) -> tuple[np.ndarray, list[str]]:
    """A CSV (header optional) or .npy file as a float matrix."""
    if not path.is_file():
        raise ImportError_(f"{path}: file not found")
    if path.suffix == ".npy":
        arr = np.load(path)
        names = [f"c{i}" for i in range(arr.shape[1] if arr.ndim == 2 else 1)]
    else:
        with open(path) as f:
            first = f.readline()
        has_header = any(c.isalpha() and c not in "eE" for c in first.replace("nan", "").replace("NaN", ""))
        try:
            arr = np.genfromtxt(path, delimiter=",", skip_header=1 if has_header else 0, dtype=float)
        except ValueError as exc:
            raise ImportError_(f"{path}: not a numeric CSV ({exc})") from None
        names = [c.strip() for c in first.strip().split(",")] if has_header else [f"c{i}" for i in range(arr.shape[1])]
    if arr.ndim == 1:
        arr = arr[:, None]
    if columns is not None:
        idx = []
        for c in columns:
            if c in names:
                idx.append(names.index(c))
            else:
                raise ImportError_(f"{path}: no column {c!r} (columns: {', '.join(names)})")
        arr = arr[:, idx]
        names = list(columns)
    if n is not None and arr.shape[1] != n:
        raise ImportError_(f"{path}: {arr.shape[1]} columns, but drives.yaml lists {n} joints")
    return arr, names


def load_npz(path: Path, time_key="times", position_key="positions", torque_key="torques",
             current_key=None) -> Recording:
    if not path.is_file():
        raise ImportError_(f"{path}: file not found")
    d = np.load(path)
    for k in (time_key, position_key):
        if k not in d:
            raise ImportError_(f"{path}: no array {k!r} (arrays: {', '.join(d.keys())})")
    tq = d[torque_key] if torque_key and torque_key in d else None
    cu = d[current_key] if current_key and current_key in d else None
    if tq is None and cu is None:
        raise ImportError_(f"{path}: neither torques ({torque_key!r}) nor currents ({current_key!r}) found")
    return Recording(t=np.asarray(d[time_key], float), position=np.asarray(d[position_key], float),
                     torque=None if tq is None else np.asarray(tq, float),
                     current=None if cu is None else np.asarray(cu, float), source=f"npz {path.name}")


def load_csvs(positions: Path, torques: Path | None = None, currents: Path | None = None, rate: float | None = None,
              time_path: Path | None = None, time_column: str | None = None, n: int | None = None) -> Recording:
    """Positions and torques (or currents) from CSVs with one column per joint; time from ``time_column`` (in the
    positions file), a separate file, or ``rate`` (Hz, uniform sampling)."""
    pos, names = _read_table(positions)
    t = None
    if time_column is not None:
        if time_column not in names:
            raise ImportError_(f"{positions}: no time column {time_column!r} (columns: {', '.join(names)})")
        k = names.index(time_column)
        t = pos[:, k]
        pos = np.delete(pos, k, axis=1)
    elif time_path is not None:
        t = _read_table(time_path)[0][:, 0]
    elif rate:
        t = np.arange(len(pos)) / float(rate)
    else:
        raise ImportError_(f"{positions}: no time: give --rate HZ, --time-column NAME or --time FILE")
    if n is not None and pos.shape[1] != n:
        raise ImportError_(f"{positions}: {pos.shape[1]} position columns, but drives.yaml lists {n} joints")
    tq = _read_table(torques, n)[0] if torques else None
    cu = _read_table(currents, n)[0] if currents else None
    if tq is None and cu is None:
        raise ImportError_(f"{positions}: give torques or currents")
    what = f"csv {positions.name}" + (f" + {torques.name}" if torques else "") + (f" + {currents.name}" if currents else "")
    return Recording(t=t, position=pos, torque=tq, current=cu, source=what)


def write_log(rec: Recording, urdf_path: Path, drives_path: Path, out: Path, robot: str | None = None,
              rate: float | None = None, positions_side: str = "motor", trials: list[tuple] | None = None,
              rows: tuple | None = None, source_text: str | None = None) -> Path:
    """Write ``rec`` as a js2 log. ``trials``: list of (name, t0, t1) seconds from the start of the recording
    (default: the whole recording as one ``excitation`` trial); each becomes trial_start/segment_start/segment_end/
    trial_end events."""
    drives = load_drives(drives_path)
    if not urdf_path.is_file():
        raise ConfigError(urdf_path, None, "file not found")
    urdf_text = urdf_path.read_text()
    # joints must match; nominal inertials may be incomplete (identification replaces them), so a zero inertia on a
    # link is accepted here where js2spec.robot.check_urdf (for simulation) would refuse it
    from .regressor import arm_model

    arm_model(urdf_text, drives, urdf_name=str(urdf_path))
    n = drives.n
    N = len(rec.t)
    for name, arr in (("positions", rec.position), ("torques", rec.torque), ("currents", rec.current)):
        if arr is None:
            continue
        if arr.shape != (N, n):
            raise ImportError_(f"{rec.source}: {name} have shape {arr.shape}; expected ({N}, {n}) (time samples x "
                               f"joints of {drives_path.name})")
    if rows is not None:
        a, b = rows
        sl = slice(a, b)
        rec = Recording(rec.t[sl], rec.position[sl], None if rec.torque is None else rec.torque[sl],
                        None if rec.current is None else rec.current[sl], rec.source)
        N = len(rec.t)
    bad = ~np.isfinite(rec.t)
    if bad.any():
        raise ImportError_(f"{rec.source}: {int(bad.sum())} time stamps are NaN/inf")
    t = rec.t - rec.t[0]
    if np.any(np.diff(t) < 0):
        raise ImportError_(f"{rec.source}: time stamps go backwards")
    rate = float(rate) if rate else float(1.0 / np.median(np.diff(t)))
    cycle = np.round(t * rate).astype(np.int64)
    first = np.concatenate([[True], np.diff(cycle) > 0])
    K = drives.gear_ratio_matrix
    if positions_side == "joint":
        qm = (rec.position - drives.joint_offset) @ np.linalg.inv(K).T
    elif positions_side == "motor":
        qm = rec.position
    else:
        raise ValueError(f"positions_side must be 'motor' or 'joint', got {positions_side!r}")
    kt = np.asarray(drives.torque_constant, float)
    tq, cu = rec.torque, rec.current
    if tq is None:
        tq = cu * kt
    if cu is None and drives.torque_side == "motor":
        cu = tq / kt
    valid = np.isfinite(qm) & np.isfinite(tq)
    nan_rows = int(np.sum(~np.all(valid, axis=1)))
    robot = robot or drives_path.parent.name or "imported"
    src = source_text or f"import:{rec.source}"
    if not src.startswith("import"):
        src = f"import:{src}"
    trials = trials or [("excitation", 0.0, float(t[-1]))]
    ev = []
    for name, t0, t1 in trials:
        t0 = max(float(t0), 0.0)
        t1 = min(float(t1), float(t[-1]))
        if t1 <= t0:
            raise ImportError_(f"{rec.source}: trial {name!r} from {t0} s to {t1} s is empty "
                               f"(recording lasts {t[-1]:.3f} s)")
        ev += [(t0, "trial_start", name), (t0, "segment_start", name), (t1, "segment_end", name),
               (t1, "trial_end", name)]
    ev.sort(key=lambda e: e[0])
    with LogWriter(out, robot=robot, cycle_hz=rate, source=src, urdf_text=urdf_text,
                   drives_yaml=drives_path.read_text()) as w:
        ei = 0
        for k in np.flatnonzero(first):
            tk = cycle[k] / rate
            while ei < len(ev) and ev[ei][0] <= tk:
                w.event(ev[ei][0], ev[ei][1], ev[ei][2])
                ei += 1
            w.feedback(int(cycle[k]), tk, np.where(valid[k], qm[k], 0.0), np.where(valid[k], tq[k], 0.0),
                       motor_current=None if cu is None else np.where(valid[k], cu[k], 0.0),
                       valid=valid[k].tolist())
        while ei < len(ev):
            w.event(ev[ei][0], ev[ei][1], ev[ei][2])
            ei += 1
        w.metadata("import", {"samples": N, "duplicates_dropped": int(N - first.sum()),
                              "rows_with_nan": nan_rows, "positions_side": positions_side})
    return out
