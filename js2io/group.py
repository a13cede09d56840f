"""DriveGroup: the n CiA 402 drives of an arm seen as one synchronous device (like python-can's BusABC).

One cycle = the master sends the command (RPDOs, applied by the drives at the NEXT SYNC) and then a SYNC, and
collects what the drives sampled at that SYNC (TPDOs). Implementations only move device units (controlword,
per-mille torque, encoder increments); the conversion to SI happens here, through `js2io.units.Scaling`.

Implementations: `js2io.canopen_group.CanopenDriveGroup` (the real path, any python-can bus) and, chosen by name
through the `js2.drive_groups` entry points (`js2io.rigs`), simulated ones such as
`hil_sim.direct.DirectDriveGroup` (steps the simulator's plant directly, no CAN; for fast log generation).
"""
from __future__ import annotations

import collections
import threading
from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np

from . import cia402
from .units import Scaling


@dataclass
class Feedback:
    cycle: int                    # +1 per SYNC
    t: float                      # s, SYNC instant on the group's clock
    motor_position: np.ndarray    # rad, motor side
    motor_current: np.ndarray     # A
    torque: np.ndarray            # N*m motor side = kt * current
    status: np.ndarray            # statusword per drive
    valid: np.ndarray             # bool per drive: this cycle's TPDO arrived
    counts: np.ndarray            # raw encoder increments (0x6064)

    def states(self) -> list[str]:
        return [cia402.state_of(int(s)) for s in self.status]


@dataclass
class Command:
    target_torque: np.ndarray                   # N*m motor side (CST)
    mode: np.ndarray | None = None              # CiA 402 mode per drive (10 CST, 9 CSV); None = current modes
    target_velocity: np.ndarray | None = None   # rad/s motor side (CSV)


@dataclass
class DriveEvent:
    kind: str            # 'fault' | 'warning' | 'emcy'
    detail: str
    joint: int | None = None
    fatal: bool = True
    code: int | None = None


@dataclass
class RawFeedback:
    status: np.ndarray        # uint16 per drive
    counts: np.ndarray        # int per drive
    current: np.ndarray       # per-mille of rated current
    received: np.ndarray      # bool per drive
    t: float | None = None    # SYNC time if the implementation measured it (real time), else None = cycle*dt


class DriveGroup(ABC):
    """Base class. Subclasses implement `open`, `_transmit`, `_sync`, `_set_modes`, `close`."""

    source = "hardware"

    def __init__(self, drives, cycle_hz: float | None = None):
        self.drives = drives
        self.n = drives.n
        self.cycle_hz = float(cycle_hz or drives.cycle_hz or 500.0)
        self.dt = 1.0 / self.cycle_hz
        self.scaling = Scaling.from_drives(drives)
        limit = drives.torque_limit if drives.torque_limit is not None else drives.rated_torque
        self.torque_limit = np.asarray(limit, dtype=float)
        self.limit_permille = self.scaling.torque_limit_permille(self.torque_limit)
        self.modes = np.full(self.n, cia402.MODE_CST, dtype=int)
        self.cycle_count = -1
        self.target_state = "disabled"
        self._cw = np.zeros(self.n, dtype=int)
        self._events: collections.deque[DriveEvent] = collections.deque()
        self._events_lock = threading.Lock()
        self.last: Feedback | None = None
        self.lost = np.zeros(self.n, dtype=int)     # TPDOs lost per drive (counted)
        self.sent: Command | None = None             # the last command as the drives received it (quantised)

    # ------------------------------------------------------------------ implementation hooks (device units)
    @abstractmethod
    def open(self) -> None:
        """Bring the drives up (NMT, SDO configuration, PDO mapping, heartbeats). Drives stay disabled."""

    @abstractmethod
    def _transmit(self, controlword: np.ndarray, torque_permille: np.ndarray, velocity_counts: np.ndarray | None) -> None:
        """Send this cycle's command (applied at the next SYNC)."""

    @abstractmethod
    def _sync(self) -> RawFeedback:
        """Send SYNC, collect what the drives sampled at it."""

    @abstractmethod
    def _set_modes(self, modes: np.ndarray) -> None:
        """Write modes of operation (0x6060) and verify them (0x6061)."""

    @abstractmethod
    def close(self) -> None:
        """Stop communication; safe to call twice."""

    # ------------------------------------------------------------------ events
    def push_event(self, ev: DriveEvent) -> None:
        with self._events_lock:
            self._events.append(ev)

    def poll_events(self) -> list[DriveEvent]:
        with self._events_lock:
            out = list(self._events)
            self._events.clear()
        return out

    # ------------------------------------------------------------------ the cycle (SI)
    def request(self, target: str) -> None:
        """Target power state for every drive: 'enabled', 'disabled', 'quick_stop'."""
        if target not in ("enabled", "disabled", "quick_stop", "reset"):
            raise ValueError(target)
        self.target_state = target

    def set_modes(self, modes) -> None:
        modes = np.broadcast_to(np.asarray(modes, dtype=int), (self.n,)).copy()
        if not np.array_equal(modes, self.modes):
            self._set_modes(modes)
            self.modes = modes

    def clamp_permille(self, tau) -> np.ndarray:
        """SI torque -> per-mille target, clamped to the configured limit (never beyond 0x6072)."""
        tau = np.nan_to_num(np.asarray(tau, dtype=float), nan=0.0, posinf=0.0, neginf=0.0)
        p = self.scaling.torque_permille(tau)
        return np.clip(p, -self.limit_permille, self.limit_permille)

    def send(self, command: Command | None) -> Command:
        """Transmit the command for the next SYNC; returns it as the drives will apply it (quantised, clamped)."""
        if command is not None and command.mode is not None:
            self.set_modes(command.mode)
        states = self.last.states() if self.last is not None else [cia402.NOT_READY] * self.n
        for i in range(self.n):
            self._cw[i] = cia402.next_controlword(states[i], self.target_state, int(self._cw[i]))
        if command is None or self.target_state != "enabled":
            p = np.zeros(self.n, dtype=np.int64)
        else:
            p = self.clamp_permille(command.target_torque)
        vel = None
        vel_si = None
        if command is not None and command.target_velocity is not None and np.any(self.modes == cia402.MODE_CSV):
            vel = self.scaling.velocity_counts(command.target_velocity)
            if self.drives.velocity_limit is not None:
                vlim = self.scaling.velocity_counts(self.drives.velocity_limit)
                vel = np.clip(vel, -vlim, vlim)
            if self.target_state != "enabled":
                vel = np.zeros(self.n, dtype=np.int64)
            vel_si = self.scaling.velocity_si(vel)
        self._transmit(self._cw.copy(), p, vel)
        self.sent = Command(target_torque=self.scaling.torque_si(p), mode=self.modes.copy(), target_velocity=vel_si)
        return self.sent

    def sync(self) -> Feedback:
        raw = self._sync()
        self.cycle_count += 1
        k = self.cycle_count
        prev = self.last
        rec = np.asarray(raw.received, dtype=bool)
        status = np.asarray(raw.status, dtype=np.int64)
        counts = np.asarray(raw.counts, dtype=np.int64)
        cur = np.asarray(raw.current, dtype=np.int64)
        if not rec.all():
            self.lost += ~rec
            if prev is not None:   # stale: keep the last values of the missing drives
                status = np.where(rec, status, prev.status)
                counts = np.where(rec, counts, prev.counts)
                cur_prev = self.scaling.current_permille(prev.motor_current)
                cur = np.where(rec, cur, cur_prev)
        current = self.scaling.current_si(cur)
        fb = Feedback(cycle=k, t=raw.t if raw.t is not None else k * self.dt,
                      motor_position=self.scaling.position_si(counts), motor_current=current,
                      torque=current * self.scaling.torque_constant, status=status, valid=rec, counts=counts)
        self.last = fb
        return fb

    def cycle(self, command: Command | None) -> Feedback:
        self.send(command)
        return self.sync()

    # ------------------------------------------------------------------ helpers
    def all_in(self, state: str) -> bool:
        return self.last is not None and all(s == state for s in self.last.states())

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def motor_position_limits(drives, margin: float = 0.05):
    """Per-motor software limits (rad) that contain the joint envelope: the box of K^-1 (q - offset) over the joint
    box [position_min, position_max], widened by `margin` of its span. The host checks the exact joint envelope;
    these (0x607D) are the drive-side backstop."""
    n = drives.n
    if drives.position_min is None or drives.position_max is None:
        return np.full(n, -np.inf), np.full(n, np.inf)
    kinv = np.linalg.inv(np.asarray(drives.gear_ratio_matrix, dtype=float))
    qmin = np.asarray(drives.position_min, dtype=float) - np.asarray(drives.joint_offset, dtype=float)
    qmax = np.asarray(drives.position_max, dtype=float) - np.asarray(drives.joint_offset, dtype=float)
    a, b = kinv * qmin[None, :], kinv * qmax[None, :]
    lo = np.minimum(a, b).sum(axis=1)
    hi = np.maximum(a, b).sum(axis=1)
    span = hi - lo
    return lo - margin * span, hi + margin * span


def motor_position_limits_counts(drives, scaling):
    lo, hi = motor_position_limits(drives)
    big = 2 ** 31 - 1
    lo_c = np.where(np.isfinite(lo), scaling.position_counts(np.where(np.isfinite(lo), lo, 0)), -big - 1)
    hi_c = np.where(np.isfinite(hi), scaling.position_counts(np.where(np.isfinite(hi), hi, 0)), big)
    return np.clip(lo_c, -big - 1, big), np.clip(hi_c, -big - 1, big)
