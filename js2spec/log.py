"""The js2 log: one MCAP file per acquisition session (``shared/spec/js2-log-v1.md``, mirrored in
``docs/log-format.md``).

:class:`LogWriter` writes it as a trial runs — small zstd chunks, flushed every ``flush_every_s`` seconds of log
time — so that a killed process leaves a file that :func:`read_log` recovers up to its last complete chunk.
:func:`read_log` returns the cycle data as arrays (:class:`Js2Log`) and refuses, with a :class:`LogError` naming
the file, anything that is not a js2 log v1.
"""
from __future__ import annotations

import datetime as _dt
import hashlib
import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterable

import numpy as np
import orjson

from .drives import DrivesConfig, parse_drives_yaml
from .errors import ConfigError, LogError
from .mcap_scan import McapScan

FORMAT = "js2-log"
VERSION = "1"
MCAP_MAGIC = b"\x89MCAP0\r\n"
TOPIC_FEEDBACK = "/js2/feedback"
TOPIC_COMMAND = "/js2/command"
TOPIC_EVENT = "/js2/event"
TOPIC_JOINT_STATE = "/js2/joint_state"
EVENT_KINDS = ("trial_start", "trial_end", "segment_start", "segment_end", "breakaway", "fault", "abort")

_num_array = {"type": "array", "items": {"type": "number"}}
SCHEMAS: dict[str, dict] = {
    TOPIC_FEEDBACK: {
        "title": "js2.Feedback", "type": "object",
        "properties": {
            "cycle": {"type": "integer", "description": "cycle counter, +1 per SYNC"},
            "t": {"type": "number", "description": "s from the first message of the file"},
            "motor_position": {**_num_array, "description": "rad, motor shaft"},
            "motor_current": {**_num_array, "description": "A"},
            "torque": {**_num_array, "description": "N*m on the side drives.yaml torque_side names"},
            "status": {"type": "array", "items": {"type": "integer"}, "description": "CiA 402 statusword"},
            "valid": {"type": "array", "items": {"type": "boolean"}},
        },
        "required": ["cycle", "t", "motor_position", "torque"],
    },
    TOPIC_COMMAND: {
        "title": "js2.Command", "type": "object",
        "properties": {
            "cycle": {"type": "integer"}, "t": {"type": "number"},
            "mode": {"type": "array", "items": {"type": "integer"}, "description": "CiA 402 mode (10 = CST)"},
            "target_torque": {**_num_array, "description": "N*m motor side"},
            "target_velocity": {**_num_array, "description": "rad/s motor side"},
            "target_position": {**_num_array, "description": "rad motor side"},
        },
        "required": ["cycle", "t", "mode", "target_torque"],
    },
    TOPIC_EVENT: {
        "title": "js2.Event", "type": "object",
        "properties": {
            "t": {"type": "number"}, "kind": {"type": "string"}, "trial": {"type": "string"},
            "joint": {"type": "integer"}, "direction": {"type": "integer"},
            "speed": {"type": "number", "description": "rad/s at the motor (magnitude)"},
            "pose": {**_num_array, "description": "joint angles, rad"},
            "value": {"type": "number"}, "detail": {"type": "string"},
        },
        "required": ["t", "kind", "trial"],
    },
    TOPIC_JOINT_STATE: {
        "title": "js2.JointState", "type": "object",
        "properties": {"name": {"type": "array", "items": {"type": "string"}}, "position": _num_array,
                       "velocity": _num_array, "effort": _num_array},
    },
}


def _list(x, n: int | None = None, kind=float) -> list:
    arr = np.asarray(x)
    if n is not None and arr.shape != (n,):
        raise ValueError(f"expected {n} values, got shape {arr.shape}")
    return [kind(v) for v in arr.tolist()]


class LogWriter:
    """Write a js2 log v1 (MCAP, JSON messages with jsonschema, zstd chunks).

    ``t`` arguments are seconds on the log's clock from the start of the file; log_time = start_ns + t * 1e9.
    Metadata and the ``robot.urdf`` / ``drives.yaml`` attachments are written when the file is opened, so a
    truncated file still carries them.
    """

    def __init__(self, path: str | Path, *, robot: str, cycle_hz: float, source: str, urdf_text: str,
                 drives_yaml: str, chunk_size: int = 64 * 1024, flush_every_s: float = 0.5,
                 start_ns: int | None = None, extra_metadata: dict[str, str] | None = None,
                 compression: str = "zstd", opener=open):
        """`opener(path, mode)` opens the file (default: the builtin `open`); tests pass one that runs out of
        space to prove the session's stop path does not depend on the log."""
        from mcap.writer import CompressionType, Writer

        self.path = Path(path)
        self.drives = parse_drives_yaml(drives_yaml, f"{self.path}:drives.yaml")
        self.n = self.drives.n
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._file = opener(self.path, "wb")
        comp = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4, "none": CompressionType.NONE}[compression]
        self._w = Writer(self._file, chunk_size=chunk_size, compression=comp)
        self._w.start(profile="", library="js2 log writer v1")
        self.start_ns = int(start_ns if start_ns is not None else _dt.datetime.now(_dt.timezone.utc).timestamp() * 1e9)
        meta = {"format": FORMAT, "version": VERSION, "robot": robot, "cycle_hz": f"{cycle_hz:g}", "source": source,
                "created": _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")}
        if extra_metadata:
            meta.update({k: str(v) for k, v in extra_metadata.items()})
        self._w.add_metadata("js2", meta)
        self._w.add_attachment(create_time=self.start_ns, log_time=self.start_ns, name="robot.urdf",
                               media_type="application/xml", data=urdf_text.encode())
        self._w.add_attachment(create_time=self.start_ns, log_time=self.start_ns, name="drives.yaml",
                               media_type="application/yaml", data=drives_yaml.encode())
        self._channels: dict[str, int] = {}
        for topic, schema in SCHEMAS.items():
            sid = self._w.register_schema(name=schema["title"], encoding="jsonschema",
                                          data=json.dumps(schema).encode())
            self._channels[topic] = self._w.register_channel(topic=topic, message_encoding="json", schema_id=sid)
        self._seq = {topic: 0 for topic in SCHEMAS}
        self._flush_every_ns = int(flush_every_s * 1e9)
        self._last_flush_ns = 0
        self.counts = {topic: 0 for topic in SCHEMAS}
        self.closed = False
        self._file.flush()

    # -- messages -------------------------------------------------------------------------------------------------
    def _add(self, topic: str, t: float, payload: dict) -> None:
        if self.closed:
            raise LogError(self.path, "log already closed")
        log_ns = self.start_ns + int(round(t * 1e9))
        seq = self._seq[topic]
        self._seq[topic] = seq + 1
        self._w.add_message(self._channels[topic], log_time=log_ns, publish_time=log_ns, sequence=seq,
                            data=json.dumps(payload, separators=(",", ":")).encode())
        self.counts[topic] += 1
        if log_ns - self._last_flush_ns >= self._flush_every_ns:
            self.flush()
            self._last_flush_ns = log_ns

    def feedback(self, cycle: int, t: float, motor_position, torque, motor_current=None, status=None,
                 valid=None) -> None:
        n = self.n
        msg: dict[str, Any] = {"cycle": int(cycle), "t": float(t), "motor_position": _list(motor_position, n),
                               "torque": _list(torque, n)}
        if motor_current is not None:
            msg["motor_current"] = _list(motor_current, n)
        if status is not None:
            msg["status"] = _list(status, n, int)
        if valid is not None:
            msg["valid"] = _list(valid, n, bool)
        self._add(TOPIC_FEEDBACK, t, msg)

    def command(self, cycle: int, t: float, mode, target_torque, target_velocity=None, target_position=None) -> None:
        n = self.n
        msg: dict[str, Any] = {"cycle": int(cycle), "t": float(t), "mode": _list(np.broadcast_to(mode, (n,)), n, int),
                               "target_torque": _list(target_torque, n)}
        if target_velocity is not None:
            msg["target_velocity"] = _list(target_velocity, n)
        if target_position is not None:
            msg["target_position"] = _list(target_position, n)
        self._add(TOPIC_COMMAND, t, msg)

    def event(self, t: float, kind: str, trial: str, **fields) -> None:
        if kind not in EVENT_KINDS:
            raise ValueError(f"unknown event kind {kind!r}; spec v1 kinds: {EVENT_KINDS}")
        msg: dict[str, Any] = {"t": float(t), "kind": kind, "trial": str(trial)}
        for k, v in fields.items():
            if v is None:
                continue
            if k in ("joint", "direction"):
                msg[k] = int(v)
            elif k in ("speed", "value"):
                msg[k] = float(v)
            elif k == "pose":
                msg[k] = _list(v)
            elif k == "detail":
                msg[k] = str(v)
            else:
                msg[k] = v if isinstance(v, (str, int, float, bool, list, dict)) else str(v)
        self._add(TOPIC_EVENT, t, msg)
        self.flush()  # events are rare and precious

    def joint_state(self, t: float, name, position, velocity, effort) -> None:
        self._add(TOPIC_JOINT_STATE, t, {"name": list(name), "position": _list(position),
                                         "velocity": _list(velocity), "effort": _list(effort)})

    def attach(self, name: str, media_type: str, data: bytes | str) -> None:
        if isinstance(data, str):
            data = data.encode()
        self._w.add_attachment(create_time=self.start_ns, log_time=self.start_ns, name=name, media_type=media_type,
                               data=data)

    def metadata(self, name: str, values: dict) -> None:
        self._w.add_metadata(name, {str(k): str(v) for k, v in values.items()})

    def flush(self, fsync: bool = False) -> None:
        """Close the open chunk and push it to the file (what a killed process would lose is only what follows)."""
        if self.closed:
            return
        self._w._Writer__finalize_chunk()  # mcap's public flush() is not in 1.6; this is what it does
        self._file.flush()
        if fsync:
            os.fsync(self._file.fileno())

    def close(self) -> None:
        if self.closed:
            return
        self._w.finish()
        self._file.flush()
        self._file.close()
        self.closed = True

    def abandon(self) -> None:
        """After a failed write: close the file without the footer (the reader recovers the complete chunks,
        `js2-repair` rewrites it). Never raises."""
        if self.closed:
            return
        self.closed = True
        try:
            self._file.close()
        except Exception:   # noqa: BLE001 - the file object itself is broken; nothing more to save
            pass

    def __enter__(self) -> "LogWriter":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


# ----------------------------------------------------------------------------------------------------------------
@dataclass
class FeedbackArrays:
    cycle: np.ndarray            # (N,) int
    t: np.ndarray                # (N,) s
    motor_position: np.ndarray   # (N, n) rad
    torque: np.ndarray           # (N, n) N*m on drives.torque_side
    motor_current: np.ndarray | None   # (N, n) A
    status: np.ndarray | None    # (N, n) int
    valid: np.ndarray            # (N, n) bool

    def __len__(self) -> int:
        return len(self.t)


@dataclass
class CommandArrays:
    cycle: np.ndarray
    t: np.ndarray
    mode: np.ndarray
    target_torque: np.ndarray
    target_velocity: np.ndarray | None
    target_position: np.ndarray | None

    def __len__(self) -> int:
        return len(self.t)


@dataclass
class Js2Log:
    path: Path
    meta: dict[str, str]
    urdf_text: str
    drives_yaml: str
    drives: DrivesConfig
    feedback: FeedbackArrays
    command_raw: list[bytes] = field(repr=False)   # /js2/command payloads, decoded on first use of .command
    events: list[dict] = field(default_factory=list)
    attachments: dict[str, bytes] = field(default_factory=dict)
    truncated: bool = False
    damage: list = field(default_factory=list)       # mcap_scan.Damage: corrupt regions skipped, a cut-off tail
    recovered_note: str = ""      # one sentence when the file was damaged or repaired; '' for an intact log
    warnings: list[str] = field(default_factory=list)
    sha256: str = ""

    @property
    def robot(self) -> str:
        return self.meta.get("robot", "")

    @property
    def data_sha256(self) -> str:
        """sha256 of what was recorded -- the feedback's times, motor positions, torques, currents and validity --
        apart from the file's metadata (its ``created`` time, ``source``), so the same recording imported or
        written twice has one ``data_sha256`` and two file ``sha256``. Made once per log."""
        if not hasattr(self, "_data_sha256"):
            fb = self.feedback
            h = hashlib.sha256()
            for a in (fb.t, fb.motor_position, fb.torque, fb.motor_current, fb.valid):
                if a is not None:
                    h.update(np.ascontiguousarray(a).tobytes())
            self._data_sha256 = h.hexdigest()
        return self._data_sha256

    @property
    def command(self) -> CommandArrays | None:
        """The /js2/command channel as arrays (None if the log has none); decoded lazily: identification rarely needs it."""
        if not hasattr(self, "_command"):
            join = getattr(self, "_command_join", None)      # a joined session: its files' commands, joined on use
            self._command = (join() if join is not None else
                             _command_arrays(self.path, self.command_raw, self.drives.n) if self.command_raw else None)
        return self._command

    @property
    def cycle_hz(self) -> float:
        return float(self.meta["cycle_hz"])

    @property
    def source(self) -> str:
        return self.meta.get("source", "")

    @property
    def lost_cycles(self) -> int:
        """Cycles missing from the counter sequence (gaps) — not counting samples flagged invalid."""
        c = self.feedback.cycle
        if len(c) < 2:
            return 0
        d = np.diff(c)
        return int(np.sum(d[d > 1] - 1))

    def trials(self) -> list[str]:
        return [e["trial"] for e in self.events if e["kind"] == "trial_start"]

    def segments(self, trial: str | None = None) -> list[tuple[dict, float]]:
        """(segment_start event, end time) pairs, optionally of one trial; an unclosed segment ends at the log end."""
        t_end = float(self.feedback.t[-1]) if len(self.feedback) else 0.0
        return segments(self.events, trial, t_end)


def segments(events: list[dict], trial: str | None, t_end: float) -> list[tuple[dict, float]]:
    """(segment_start event, end time) pairs from a log's events, optionally of one trial only; a segment that is
    never closed ends at ``t_end``."""
    out, open_ = [], None
    for e in events:
        if trial is not None and e.get("trial") != trial:
            continue
        if e["kind"] == "segment_start":
            if open_ is not None:
                out.append((open_, e["t"]))
            open_ = e
        elif e["kind"] == "segment_end" and open_ is not None:
            out.append((open_, e["t"]))
            open_ = None
    if open_ is not None:
        out.append((open_, t_end))
    return out


def file_sha256(path: str | Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def read_log(path: str | Path) -> Js2Log:
    """Read a js2 log v1 into arrays. Damaged files are read around the damage (``damage``, ``recovered_note``):
    a truncated tail up to the last complete chunk, a corrupt chunk mid-file skipped (`js2spec.mcap_scan`)."""
    from mcap.records import Attachment, Channel, Message, Metadata

    path = Path(path)
    if path.is_dir():
        raise LogError(path, "is a folder, not a log file; give the .mcap file inside it")
    if not path.is_file():
        raise LogError(path, "file not found")
    with open(path, "rb") as f:
        head = f.read(len(MCAP_MAGIC))
    if head != MCAP_MAGIC:
        raise LogError(path, "not an MCAP file (bad magic bytes); a js2 log is MCAP, see docs/log-format.md")

    meta: dict[str, str] | None = None
    attachments: dict[str, bytes] = {}
    channels: dict[int, str] = {}
    msgs: dict[str, list] = {TOPIC_FEEDBACK: [], TOPIC_COMMAND: [], TOPIC_EVENT: []}
    repair: dict[str, str] | None = None
    scan = McapScan(path)
    for rec in scan.records():
        if isinstance(rec, Message):
            topic = channels.get(rec.channel_id)
            if topic in msgs:
                msgs[topic].append(rec.data)
        elif isinstance(rec, Channel):
            channels[rec.id] = rec.topic
        elif isinstance(rec, Metadata):
            if rec.name == "js2":
                meta = dict(rec.metadata)
            elif rec.name == "js2_repair":
                repair = dict(rec.metadata)
        elif isinstance(rec, Attachment):
            attachments[rec.name] = bytes(rec.data)

    if meta is None:
        damaged = f" (the file is damaged: {scan.note()})" if scan.damage else ""
        raise LogError(path, f"no 'js2' metadata record: not a js2 log (or truncated before its header){damaged}")
    if meta.get("format") != FORMAT:
        raise LogError(path, f"metadata format is {meta.get('format')!r}, expected {FORMAT!r}")
    if meta.get("version") != VERSION:
        raise LogError(path, f"js2 log version {meta.get('version')!r} is not supported (this reader knows "
                             f"version {VERSION}); upgrade js2 or convert the file")
    for key in ("robot", "cycle_hz", "source"):
        if key not in meta:
            raise LogError(path, f"'js2' metadata lacks the key {key!r}")
    try:
        float(meta["cycle_hz"])
    except ValueError:
        raise LogError(path, f"'js2' metadata cycle_hz={meta['cycle_hz']!r} is not a number") from None
    for name in ("robot.urdf", "drives.yaml"):
        if name not in attachments:
            raise LogError(path, f"required attachment {name!r} is missing")
    drives_yaml = attachments["drives.yaml"].decode()
    try:
        drives = parse_drives_yaml(drives_yaml, f"{path}:drives.yaml")
    except ConfigError as exc:
        raise LogError(path, f"attached drives.yaml is invalid: {exc.problem} (key {exc.key})") from None
    if TOPIC_FEEDBACK not in channels.values():
        raise LogError(path, f"required channel {TOPIC_FEEDBACK} is missing")

    n = drives.n
    warnings: list[str] = []
    feedback = _feedback_arrays(path, msgs[TOPIC_FEEDBACK], n, drives.torque_side, warnings)
    events = []
    for raw in msgs[TOPIC_EVENT]:
        try:
            e = json.loads(raw)
        except ValueError:
            raise LogError(path, f"an {TOPIC_EVENT} message is not JSON") from None
        if not {"t", "kind", "trial"} <= e.keys():
            raise LogError(path, f"an {TOPIC_EVENT} message lacks t/kind/trial: {e}")
        events.append(e)
    events.sort(key=lambda e: e["t"])
    truncated = scan.truncated
    note = ""
    if scan.damage or truncated:
        where = ("up to the last complete chunk" if not any(d.kind == "corrupt" for d in scan.damage)
                 else "around the damage")
        note = (f"log was recovered ({scan.note()}); read {len(feedback)} feedback cycles "
                f"({feedback.t[-1] if len(feedback) else 0:.3f} s) and {len(events)} events {where}; "
                f"`js2-repair {path}` rewrites it as a complete MCAP")
    elif repair is not None:
        note = f"log was repaired by js2-repair from {repair.get('source', '?')}: {repair.get('damage', '')}"
    return Js2Log(path=path, meta=meta, urdf_text=attachments["robot.urdf"].decode(), drives_yaml=drives_yaml,
                  drives=drives, feedback=feedback, command_raw=msgs[TOPIC_COMMAND], events=events, attachments=attachments,
                  truncated=truncated, damage=list(scan.damage), recovered_note=note, warnings=warnings, sha256=file_sha256(path))


def _decode_all(path: Path, raws: list[bytes], topic: str) -> list[dict]:
    """Every message of a topic decoded at once. orjson first (about twice Python's json on a feedback channel: the
    speed bench's 8 files read in 3.1-3.7 s instead of 4.5-4.9); where it refuses (the NaN/Infinity literals
    Python's json writes, which orjson does not read), Python's json, which reads them and names a message that is
    no JSON."""
    blob = b"[" + b",".join(raws) + b"]"
    try:
        return orjson.loads(blob)
    except orjson.JSONDecodeError:
        pass
    try:
        return json.loads(blob)
    except ValueError:
        for i, raw in enumerate(raws):
            try:
                json.loads(raw)
            except ValueError:
                raise LogError(path, f"{topic} message #{i} is not valid JSON") from None
        raise


def _matrix(path: Path, rows: list, topic: str, key: str, n: int) -> np.ndarray:
    try:
        arr = np.asarray(rows, dtype=float)
    except (ValueError, TypeError):
        bad = next((i for i, r in enumerate(rows) if not isinstance(r, list) or len(r) != n), 0)
        raise LogError(path, f"{topic} field '{key}' of message #{bad} has {len(rows[bad]) if isinstance(rows[bad], list) else '?'}"
                             f" entries; drives.yaml lists {n} joints") from None
    if arr.ndim != 2 or arr.shape[1] != n:
        raise LogError(path, f"{topic} field '{key}' has {arr.shape[1] if arr.ndim == 2 else '?'} entries per "
                             f"message; drives.yaml lists {n} joints")
    return arr


def _feedback_arrays(path: Path, raws: list[bytes], n: int, torque_side: str, warnings: list[str]) -> FeedbackArrays:
    if not raws:
        raise LogError(path, f"channel {TOPIC_FEEDBACK} holds no messages")
    msgs = _decode_all(path, raws, TOPIC_FEEDBACK)
    for key in ("cycle", "t", "motor_position", "torque"):
        if any(key not in m for m in msgs):
            raise LogError(path, f"{TOPIC_FEEDBACK} messages lack the required field '{key}'")
    order = np.argsort([m["t"] for m in msgs], kind="stable")
    msgs = [msgs[i] for i in order]
    cycle = np.asarray([m["cycle"] for m in msgs], dtype=np.int64)
    t = np.asarray([m["t"] for m in msgs], dtype=float)
    pos = _matrix(path, [m["motor_position"] for m in msgs], TOPIC_FEEDBACK, "motor_position", n)
    tau = _matrix(path, [m["torque"] for m in msgs], TOPIC_FEEDBACK, "torque", n)
    cur = None
    if all("motor_current" in m for m in msgs):
        cur = _matrix(path, [m["motor_current"] for m in msgs], TOPIC_FEEDBACK, "motor_current", n)
    elif torque_side == "motor":
        raise LogError(path, f"{TOPIC_FEEDBACK} lacks 'motor_current', required when torque_side is 'motor'")
    status = None
    if all("status" in m for m in msgs):
        status = _matrix(path, [m["status"] for m in msgs], TOPIC_FEEDBACK, "status", n).astype(np.int64)
    if all("valid" in m for m in msgs):
        valid = _matrix(path, [m["valid"] for m in msgs], TOPIC_FEEDBACK, "valid", n).astype(bool)
    else:
        valid = np.ones((len(msgs), n), dtype=bool)
    finite = np.isfinite(pos) & np.isfinite(tau)
    if cur is not None:
        finite &= np.isfinite(cur)
    bad = valid & ~finite
    if bad.any():
        warnings.append(f"{int(bad.sum())} feedback values were NaN/inf where 'valid' was true; "
                        f"those samples are marked invalid")
        valid = valid & finite
    if not np.all(np.isfinite(t)):
        raise LogError(path, f"{TOPIC_FEEDBACK} field 't' contains NaN/inf")
    return FeedbackArrays(cycle=cycle, t=t, motor_position=pos, torque=tau, motor_current=cur, status=status,
                          valid=valid)


def _command_arrays(path: Path, raws: list[bytes], n: int) -> CommandArrays:
    msgs = _decode_all(path, raws, TOPIC_COMMAND)
    msgs.sort(key=lambda m: m["t"])
    tv = [m.get("target_velocity") for m in msgs]
    tp = [m.get("target_position") for m in msgs]
    return CommandArrays(
        cycle=np.asarray([m["cycle"] for m in msgs], dtype=np.int64),
        t=np.asarray([m["t"] for m in msgs], dtype=float),
        mode=_matrix(path, [m["mode"] for m in msgs], TOPIC_COMMAND, "mode", n).astype(np.int64),
        target_torque=_matrix(path, [m["target_torque"] for m in msgs], TOPIC_COMMAND, "target_torque", n),
        target_velocity=(_matrix(path, [v if v is not None else [math.nan] * n for v in tv], TOPIC_COMMAND,
                                 "target_velocity", n) if any(v is not None for v in tv) else None),
        target_position=(_matrix(path, [v if v is not None else [math.nan] * n for v in tp], TOPIC_COMMAND,
                                 "target_position", n) if any(v is not None for v in tp) else None),
    )


def read_logs(paths: Iterable[str | Path]) -> list[Js2Log]:
    return [read_log(p) for p in paths]


def join_logs(logs: list[Js2Log], gap_cycles: int = 50) -> Js2Log:
    """One session recorded over several files, as one log: feedback, commands and events of each file after the
    previous one's end, ``gap_cycles`` cycles apart (a gap longer than any bridged loss, so filters treat each file
    as its own run and never smooth across a file boundary). The files must record the same arm (robot, drives,
    URDF) at the same cycle rate; otherwise :class:`LogError` names the first that differs. A single log is returned
    unchanged. ``path`` is the first file's; ``meta['joined_from']`` lists them all."""
    if not logs:
        raise ValueError("join_logs: no logs")
    if len(logs) == 1:
        return logs[0]
    first = logs[0]
    for lg in logs[1:]:
        for what, a, b in (("robot", first.robot, lg.robot), ("cycle_hz", first.meta.get("cycle_hz"),
                                                              lg.meta.get("cycle_hz")),
                           ("drives.yaml", first.drives_yaml, lg.drives_yaml), ("robot.urdf", first.urdf_text,
                                                                                lg.urdf_text)):
            if a != b:
                raise LogError(lg.path, f"{what} differs from {first.path}'s: the recordings of one command must be "
                                        f"one arm's session; diagnose them one at a time")
    dt = 1.0 / first.cycle_hz
    fbs, cmds, events, warnings, notes = [], [], [], [], []
    t_next, c_next = 0.0, 0
    for lg in logs:
        fb = lg.feedback
        if len(fb) == 0:
            continue
        dt_shift, dc_shift = t_next - float(fb.t[0]), c_next - int(fb.cycle[0])
        fbs.append((fb, dt_shift, dc_shift))
        cmds.append((lg, dt_shift, dc_shift))
        events += [dict(e, t=float(e["t"]) + dt_shift) for e in lg.events]
        warnings += [f"{lg.path.name}: {w}" for w in lg.warnings]
        if lg.recovered_note:
            notes.append(f"{lg.path.name}: {lg.recovered_note}")
        t_next = float(fb.t[-1]) + dt_shift + gap_cycles * dt
        c_next = int(fb.cycle[-1]) + dc_shift + gap_cycles

    def cat(arrs, name):
        vals = [getattr(a, name) for a, _, _ in arrs]
        return None if any(v is None for v in vals) else np.concatenate(vals)

    feedback = FeedbackArrays(cycle=np.concatenate([f.cycle + dc for f, _, dc in fbs]),
                              t=np.concatenate([f.t + dt_ for f, dt_, _ in fbs]),
                              motor_position=cat(fbs, "motor_position"), torque=cat(fbs, "torque"),
                              motor_current=cat(fbs, "motor_current"), status=cat(fbs, "status"),
                              valid=cat(fbs, "valid"))
    joined = Js2Log(path=first.path, meta=dict(first.meta, joined_from=", ".join(str(lg.path) for lg in logs)),
                    urdf_text=first.urdf_text, drives_yaml=first.drives_yaml, drives=first.drives, feedback=feedback,
                    command_raw=[], events=sorted(events, key=lambda e: e["t"]), attachments=first.attachments,
                    truncated=any(lg.truncated for lg in logs), damage=[d for lg in logs for d in lg.damage],
                    recovered_note="; ".join(notes), warnings=warnings,
                    sha256=",".join(lg.sha256 for lg in logs))

    def command():
        """The files' commands joined like their feedback (decoded on first use: the diagnosis of a session
        without static trials never reads them, 0.1 s per 40 s file); None unless every file with feedback has
        them."""
        parts = [(lg.command, dt_, dc) for lg, dt_, dc in cmds]
        parts = [(c, dt_, dc) for c, dt_, dc in parts if c is not None and len(c)]
        if not parts or len(parts) != len(fbs):
            return None
        return CommandArrays(cycle=np.concatenate([c.cycle + dc for c, _, dc in parts]),
                             t=np.concatenate([c.t + dt_ for c, dt_, _ in parts]), mode=cat(parts, "mode"),
                             target_torque=cat(parts, "target_torque"),
                             target_velocity=cat(parts, "target_velocity"),
                             target_position=cat(parts, "target_position"))

    joined._command_join = command
    return joined


def damage_notes(paths: Iterable[str | Path]) -> list[str]:
    """'<path>: <what was lost>' for each damaged log among `paths` (truncated, corrupt, repaired): what a CLI adds
    to an error met on such a log ("no velocity trial" may only mean the trial was in the lost part). Files that do
    not start with MCAP's magic bytes are not logs with a lost part (read_log refuses them as not MCAP): no note."""
    out = []
    for p in paths:
        p = Path(p)
        if not p.is_file():
            continue
        try:
            with open(p, "rb") as f:
                if f.read(len(MCAP_MAGIC)) != MCAP_MAGIC:
                    continue          # not an MCAP file at all (read_log says so): nothing was lost from it
            scan = McapScan(p)
            for rec in scan.records():
                if rec.__class__.__name__ == "Metadata" and rec.name == "js2_repair":
                    out.append(f"{p}: repaired by js2-repair ({rec.metadata.get('damage', '')})")
            if scan.damage or not scan.complete:
                out.append(f"{p}: {scan.note()}")
        except Exception:   # noqa: BLE001 - this only adds context to an error already being reported
            continue
    return out
