"""Plain recordings (CSV or NumPy arrays of time, positions, torques or currents) + URDF + drives file -> js2 log.

The log is written through ``js2spec.log.LogWriter`` with source ``import:<what>``, so any arm's recording can be
identified by ``js2-identify`` like our own logs. Samples go on the cycle grid ``cycle = round((t - t0) * rate)``;
duplicated cycles are dropped (first kept) and missing ones stay missing (the reader sees them as lost cycles: no
silent resampling). Positions are motor-side angles in the log: joint-side recordings are converted with
``theta_m = K^-1 (theta - offset)``. With ``torque_side: motor`` a log needs currents: given only torques, the current
is ``torque / torque_constant`` (and vice versa).
"""
from __future__ import annotations

import os
import zipfile
import zlib
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


TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6}
MISSING = ("", "nan", "NaN", "NAN", "NA", "n/a")     # cells read as missing (NaN): the NaN policy decides


def _read_csv(path: Path) -> tuple[np.ndarray, list[str]]:
    """A numeric CSV (header optional) as a float matrix. Empty and 'nan'/'NA' cells are NaN (missing); any other
    cell that is not a number is refused with its row and column (never silently NaN)."""
    import csv

    from js2spec.files import read_text
    text = read_text(path, "CSV file")
    rows = list(csv.reader(text.splitlines()))
    if not rows:
        raise ImportError_(f"{path}: empty file")
    first = [c.strip() for c in rows[0]]

    def is_num(c):
        try:
            float(c)
            return True
        except ValueError:
            return c in MISSING
    has_header = not all(is_num(c) for c in first)
    names = first if has_header else [f"c{i}" for i in range(len(first))]
    body = rows[1:] if has_header else rows
    body = [r for r in body if r and any(c.strip() for c in r)]
    if not body:
        raise ImportError_(f"{path}: no data rows")
    width = len(names)
    arr = np.full((len(body), width), np.nan)
    bad = []
    line0 = 2 if has_header else 1
    for i, r in enumerate(body):
        if len(r) != width:
            raise ImportError_(f"{path}: data row {i + line0} has {len(r)} cells, the header {width}; "
                               f"fix the row or the delimiter (comma expected)")
        for j, c in enumerate(r):
            c = c.strip()
            try:
                arr[i, j] = float(c)
            except ValueError:
                if c not in MISSING:
                    bad.append((i + line0, names[j], c))
    if bad:
        shown = "; ".join(f"line {ln}, column {col!r}: {val[:20]!r}" for ln, col, val in bad[:3])
        more = f" (and {len(bad) - 3} more)" if len(bad) > 3 else ""
        raise ImportError_(f"{path}: {len(bad)} cells are not numbers: {shown}{more}; fix them or leave them "
                           f"empty (empty = missing, handled by --nan)")
    return arr, names


def _read_table(path: Path, n: int | None = None, columns=None) -> tuple[np.ndarray, list[str]]:
    """A CSV (header optional) or .npy file as a float matrix."""
    if path.is_dir():
        raise ImportError_(f"{path}: is a folder; give the file")
    if not path.is_file():
        raise ImportError_(f"{path}: file not found")
    if path.suffix == ".npy":
        try:
            arr = np.asarray(np.load(path, allow_pickle=False), dtype=float)
        except (ValueError, OSError, TypeError) as exc:
            raise ImportError_(f"{path}: not a numeric .npy array ({' '.join(str(exc).split())[:80]})") from None
        names = [f"c{i}" for i in range(arr.shape[1] if arr.ndim == 2 else 1)]
    else:
        arr, names = _read_csv(path)
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
    if path.is_dir():
        raise ImportError_(f"{path}: is a folder; give the .npz file")
    if not path.is_file():
        raise ImportError_(f"{path}: file not found")
    # a truncated or damaged archive fails in the zip reader (BadZipFile), or later in one member's inflate (zlib's
    # error, EOFError) or its header (ValueError): each is said in one line, with what to do
    damaged = (ValueError, OSError, EOFError, zipfile.BadZipFile, zlib.error)
    try:
        d = np.load(path, allow_pickle=False)
        d.keys()
    except damaged as exc:
        raise ImportError_(f"{path}: not a NumPy .npz archive, or a damaged one ({' '.join(str(exc).split())[:80]}); "
                           "save it again with numpy.savez") from None
    for k in (time_key, position_key):
        if k not in d:
            raise ImportError_(f"{path}: no array {k!r} (arrays: {', '.join(d.keys())})")
    try:
        tq = d[torque_key] if torque_key and torque_key in d else None
        cu = d[current_key] if current_key and current_key in d else None
        t, pos = d[time_key], d[position_key]
    except damaged as exc:
        raise ImportError_(f"{path}: an array in the archive cannot be read, the file is damaged or cut short "
                           f"({' '.join(str(exc).split())[:80]}); save it again with numpy.savez") from None
    if tq is None and cu is None:
        raise ImportError_(f"{path}: neither torques ({torque_key!r}) nor currents ({current_key!r}) found")
    return Recording(t=np.asarray(t, float), position=np.asarray(pos, float),
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


def check_time_step(t: np.ndarray, source: str, time_unit: str) -> None:
    """Servo recordings are sampled at 50 Hz..50 kHz; a median step outside that is a unit mistake: say which."""
    dt = float(np.median(np.diff(t))) if len(t) > 1 else 0.0
    if not dt > 0:
        raise ImportError_(f"{source}: time stamps do not advance (median step {dt:g})")
    hz = 1.0 / dt
    if hz < 50.0:
        hint = ", ".join(f"{u}: {hz / f * TIME_UNITS[time_unit]:.0f} Hz" for u, f in TIME_UNITS.items()
                         if u != time_unit and 50 <= hz / f * TIME_UNITS[time_unit] <= 50_000)
        raise ImportError_(f"{source}: median time step {dt:g} s ({hz:.3g} Hz) is not a servo rate; is the time "
                           f"in another unit? Pass --time-unit ({hint or 's, ms or us'}) or --rate HZ")
    if hz > 50_000:
        raise ImportError_(f"{source}: median time step {dt:g} s ({hz:.3g} Hz) is faster than any servo log; check "
                           f"the time column and --time-unit")


def write_log(rec: Recording, urdf_path: Path, drives_path: Path, out: Path, robot: str | None = None,
              rate: float | None = None, positions_side: str = "motor", trials: list[tuple] | None = None,
              rows: tuple | None = None, source_text: str | None = None, time_unit: str = "s",
              nan_policy: str = "mark", unit_check: bool = True, report: dict | None = None) -> Path:
    """Write ``rec`` as a js2 log. ``trials``: list of (name, t0, t1) seconds from the start of the recording
    (default: the whole recording as one ``excitation`` trial); each becomes trial_start/segment_start/segment_end/
    trial_end events."""
    from js2spec.files import read_text
    drives = load_drives(drives_path)
    urdf_text = read_text(urdf_path, "URDF")
    # joints must match; nominal inertials may be incomplete (identification replaces them), so a zero inertia on a
    # link is accepted here where js2spec.robot.check_urdf (for simulation) would refuse it
    from .regressor import arm_model

    arm = arm_model(urdf_text, drives, urdf_name=str(urdf_path))
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
    if time_unit not in TIME_UNITS:
        raise ImportError_(f"time unit {time_unit!r}: one of {', '.join(TIME_UNITS)}")
    t = (rec.t - rec.t[0]) * TIME_UNITS[time_unit]
    if np.any(np.diff(t) < 0):
        raise ImportError_(f"{rec.source}: time stamps go backwards")
    if not rate:
        check_time_step(t, rec.source, time_unit)
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
    if nan_rows and nan_policy == "refuse":
        k = int(np.flatnonzero(~np.all(valid, axis=1))[0])
        raise ImportError_(f"{rec.source}: {nan_rows} samples have missing/NaN values (first at sample {k}, "
                           f"t = {t[k]:.4f} s); --nan mark imports them as invalid samples instead")
    if nan_policy not in ("mark", "refuse"):
        raise ImportError_(f"NaN policy {nan_policy!r}: 'mark' or 'refuse'")
    if nan_rows * 2 > N:
        raise ImportError_(f"{rec.source}: {nan_rows} of {N} samples have missing/NaN values; too few to identify "
                           f"from (check the columns and the delimiter)")
    if unit_check:
        from .unit_check import check_torque_units
        check_torque_units(arm, t, qm, tq, rec.source)
    if report is not None:
        report.update(samples=N, nan_rows=nan_rows, rate_hz=rate)
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
    # written beside OUT and renamed over it when complete: a reader never sees half a file (two processes importing
    # the same recording, or an interrupted import, used to leave one; a symlink at OUT is replaced, not written
    # through)
    out = Path(out)
    part = out.with_name(f".{out.name}.{os.getpid()}.part")
    try:
        with LogWriter(part, robot=robot, cycle_hz=rate, source=src, urdf_text=urdf_text,
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
                                  "rows_with_nan": nan_rows, "nan_policy": nan_policy, "positions_side": positions_side,
                                  "time_unit": time_unit, "unit_check": "on" if unit_check else "off"})
        os.replace(part, out)
    finally:
        part.unlink(missing_ok=True)
    return out
