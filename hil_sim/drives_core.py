"""The simulated servo drives, independent of CAN: n CiA 402 drives around one `hil_sim.plant.Plant`.

`SimDriveSet` is what the CANopen slaves (`hil_sim.drives`) and the CAN-less `hil_sim.direct.DirectDriveGroup`
share, so both behave identically: the power state machine, modes 10 (CST) and 9 (CSV), max torque 0x6072,
software position limits 0x607D, quick stop, faults with EMCY codes, and fault injection. Device units on the
outside (controlword, per-mille, encoder increments); SI inside.

Timing per SYNC (CiA 301): sample the sensors (-> TPDO), latch the RPDOs received since the last SYNC, compute
the motor torque and step the plant one period (lock-step) -- `on_sync()`.
"""
from __future__ import annotations

import math
import threading
from dataclasses import dataclass

import numpy as np

from js2io import cia402
from js2io.cia402 import (EMCY_GENERIC, EMCY_HEARTBEAT, EMCY_NAMES, EMCY_OVERCURRENT,  # noqa: F401 - re-exported
                          EMCY_POSITION_LIMIT, ENABLED, FAULT, FAULT_REACTION, QUICK_STOP, READY, STATUS_BITS,
                          SWITCH_ON_DISABLED, SWITCHED_ON)
from js2spec.errors import ConfigError

FAULT_KINDS = ("dead_node", "lost_frames", "drive_fault", "bus_error", "heartbeat_loss")


@dataclass
class Fault:
    """A fault to inject: `kind` at SYNC number `at_cycle` on drive `drive` (0-based; None = all / n.a.)."""
    kind: str
    at_cycle: int = 0
    drive: int | None = None
    count: int = 1          # lost_frames: how many consecutive TPDOs of that drive are dropped
    code: int = EMCY_OVERCURRENT   # drive_fault: EMCY / 0x603F code

    @classmethod
    def parse(cls, text: str) -> "Fault":
        """'KIND[:DRIVE][@CYCLE][xCOUNT]', e.g. 'drive_fault:2@300', 'lost_frames:1@200x20', 'bus_error@400'."""
        s = text.strip()
        try:
            count = 1
            if "x" in s.split("@")[-1] and "@" in s:
                s, c = s.rsplit("x", 1)
                count = int(c)
            at = 0
            if "@" in s:
                s, a = s.split("@", 1)
                at = int(a)
            drive = None
            if ":" in s:
                s, d = s.split(":", 1)
                drive = int(d)
            kind = s
        except ValueError:
            raise ConfigError(None, "fault", f"cannot parse {text!r}; write KIND[:DRIVE][@CYCLE][xCOUNT], "
                              f"e.g. drive_fault:2@300 or lost_frames:1@200x20") from None
        if kind not in FAULT_KINDS:
            raise ConfigError(None, "fault", f"unknown fault kind {kind!r} in {text!r}; one of {', '.join(FAULT_KINDS)}")
        if kind in ("dead_node", "lost_frames", "drive_fault") and drive is None:
            raise ConfigError(None, "fault", f"{text!r}: {kind} needs a drive index, e.g. {kind}:2@300")
        return cls(kind=kind, at_cycle=at, drive=drive, count=count)


class DriveCore:
    """One simulated CiA 402 drive (device units in, motor torque in N*m out)."""

    def __init__(self, rated_torque: float, rated_current: float, counts_per_rev: int, dt: float,
                 velocity_gain: float | None = None):
        self.rated_torque = float(rated_torque)
        self.rated_current = float(rated_current)
        self.cpr = int(counts_per_rev)
        self.dt = float(dt)
        self.state = SWITCH_ON_DISABLED
        self.controlword = 0
        self.mode = cia402.MODE_CST           # 0x6060
        self.mode_display = cia402.MODE_CST   # 0x6061
        self.target_torque = 0                # 0x6071 per-mille
        self.target_velocity = 0              # 0x60FF increments/s
        self.max_torque = 1000                # 0x6072 per-mille
        self.pos_min = -(2 ** 31)             # 0x607D:1 increments
        self.pos_max = 2 ** 31 - 1            # 0x607D:2
        self.error_code = 0                   # 0x603F
        self.internal_limit = False
        self.internal_qs = False              # quick stop raised by the drive itself (not by the controlword)
        self.kd = velocity_gain if velocity_gain is not None else self.rated_torque / 60.0   # N*m per rad/s
        self.ki = self.kd * 30.0
        self.kp_hold = self.kd * 25.0
        self._integ = 0.0
        self._hold_pos = None
        self._prev_counts = None
        self.velocity = 0.0                   # rad/s, filtered estimate from the encoder
        self.brake_torque = self.rated_torque  # N*m, holding brake (engaged when not operation enabled)
        self._pos = 0.0

    # -- state machine ---------------------------------------------------------------------------------
    def statusword(self) -> int:
        sw = STATUS_BITS[self.state] | 0x0200          # bit 9 remote
        if self.state in (READY, SWITCHED_ON, ENABLED, QUICK_STOP, FAULT_REACTION):
            sw |= 0x0010                               # voltage enabled
        if self.internal_limit:
            sw |= 0x0800
        if self.state == ENABLED:
            sw |= 0x1000                               # CST/CSV: drive follows the target
        if self.state in (FAULT, FAULT_REACTION):
            sw &= ~0x0020 & 0xFFFF
        return sw

    def on_controlword(self, cw: int) -> None:
        prev = self.controlword
        self.controlword = cw
        st = self.state
        if st == FAULT:
            if cw & 0x80 and not prev & 0x80:
                self.state = SWITCH_ON_DISABLED
                self.error_code = 0
                self.internal_qs = False
            return
        if st in (FAULT_REACTION,):
            return
        disable_voltage = not cw & 0x02
        quick_stop = (cw & 0x06) == 0x02
        shutdown = (cw & 0x87) == 0x06
        switch_on = (cw & 0x8F) == 0x07
        enable = (cw & 0x8F) == 0x0F
        if st == SWITCH_ON_DISABLED:
            if shutdown:
                self.state = READY
        elif st == READY:
            if disable_voltage or quick_stop:
                self.state = SWITCH_ON_DISABLED
            elif switch_on:
                self.state = SWITCHED_ON
            elif enable:
                self._enter_enabled()
        elif st == SWITCHED_ON:
            if disable_voltage or quick_stop:
                self.state = SWITCH_ON_DISABLED
            elif shutdown:
                self.state = READY
            elif enable:
                self._enter_enabled()
        elif st == ENABLED:
            if disable_voltage:
                self.state = SWITCH_ON_DISABLED
            elif quick_stop:
                self._enter_quick_stop(internal=False)
            elif shutdown:
                self.state = READY
            elif switch_on:
                self.state = SWITCHED_ON
        elif st == QUICK_STOP:
            if disable_voltage:
                self.state = SWITCH_ON_DISABLED
                self.internal_qs = False
            elif enable and not self.internal_qs:
                self._enter_enabled()   # transition 16 (0x605A = 6 allows it)

    def hold_torque(self) -> float:
        """Brake to standstill and hold the position latched when holding began (PD, damping ratio ~0.7)."""
        if self._hold_pos is None:
            self._hold_pos = self._pos
        return self.kp_hold * (self._hold_pos - self._pos) - self.kd * self.velocity

    def _enter_enabled(self) -> None:
        self._hold_pos = None
        self.state = ENABLED
        self._integ = 0.0
        self.mode_display = self.mode

    def _enter_quick_stop(self, internal: bool) -> None:
        self._standstill = 0
        self.state = QUICK_STOP
        self.internal_qs = internal
        self._hold_pos = None

    def quick_stop(self) -> bool:
        """Drive-internal quick stop (e.g. the master's heartbeat stopped). True if it changed anything."""
        if self.state == ENABLED:
            self._enter_quick_stop(internal=True)
            return True
        return False

    def fault(self, code: int) -> bool:
        """Raise a fault; True if this is a new one (the caller sends the EMCY)."""
        if self.state in (FAULT, FAULT_REACTION):
            return False
        self.error_code = code
        self.state = FAULT_REACTION
        self._hold_pos = None
        return True

    def set_mode(self, mode: int) -> None:
        if mode not in (cia402.MODE_CST, cia402.MODE_CSV):
            raise ValueError(f"mode {mode} not supported (0x6502: CST 10, CSV 9)")
        self.mode = mode
        self.mode_display = mode
        self._integ = 0.0

    # -- one period ------------------------------------------------------------------------------------
    def update_velocity(self, counts: int) -> None:
        if self._prev_counts is not None:
            v = (counts - self._prev_counts) * 2 * math.pi / self.cpr / self.dt
            self.velocity += 0.5 * (v - self.velocity)
        self._prev_counts = counts
        self._pos = counts * 2 * math.pi / self.cpr

    def torque(self, counts: int) -> tuple[float, int | None]:
        """Motor torque (N*m) to apply for the next period, and a new fault code if one arose."""
        new_fault = None
        lim = self.max_torque * self.rated_torque / 1000.0
        self.internal_limit = False
        if self.state == ENABLED and not (self.pos_min <= counts <= self.pos_max):
            new_fault = EMCY_POSITION_LIMIT if self.fault(EMCY_POSITION_LIMIT) else None
        st = self.state
        if st == ENABLED:
            if self.mode_display == cia402.MODE_CSV:
                vt = self.target_velocity * 2 * math.pi / self.cpr
                e = vt - self.velocity
                tau = self.kd * e + self._integ
                if abs(tau) < lim:
                    self._integ += self.ki * e * self.dt
                tau = self.kd * e + self._integ
            else:
                tau = self.target_torque * self.rated_torque / 1000.0
        else:
            # QUICK STOP / FAULT REACTION: the drive brakes and holds the motor; any other state: the holding brake
            # (spring-applied, engaged whenever the drive does not hold the motor itself) does the same, up to the
            # brake torque, so a disabled simulated arm does not fall (a real one has brakes)
            tau = self.hold_torque()
            if st == FAULT_REACTION:
                self.state = FAULT   # fault reaction completes within one period
            elif st == QUICK_STOP and self.internal_qs:
                # a quick stop the drive raised itself (master lost): once at standstill, disable (brake holds);
                # option code 2 semantics -- a commanded quick stop stays in QUICK STOP ACTIVE (0x605A = 6)
                self._standstill = self._standstill + 1 if abs(self.velocity) < 0.5 else 0
                if self._standstill >= 25:
                    self.state = SWITCH_ON_DISABLED
                    self.internal_qs = False
            if st not in (QUICK_STOP, FAULT_REACTION):
                lim = self.brake_torque
        if abs(tau) > lim:
            tau = math.copysign(lim, tau)
            self.internal_limit = True
        return tau, new_fault


class SimDriveSet:
    """n drives around one plant; lock-step: one `on_sync()` per SYNC."""

    def __init__(self, robot, plant=None, cycle_hz: float | None = None, seed: int | None = None,
                 faults: list[Fault] | None = None, q0=None):
        from hil_sim.plant import Plant

        self.robot = robot
        d = robot.drives
        self.n = d.n
        self.cycle_hz = float(cycle_hz or d.cycle_hz or 500.0)
        self.dt = 1.0 / self.cycle_hz
        self.plant = plant if plant is not None else Plant(robot, seed=seed)
        if q0 is not None:
            self.plant.reset(np.asarray(q0, dtype=float))
        if d.rated_torque is None or d.rated_current is None:
            raise ConfigError(d.source, "rated_torque", "the simulated drives need rated_torque and rated_current")
        self.cores = [DriveCore(d.rated_torque[i], d.rated_current[i], int(d.encoder_counts_per_rev[i]), self.dt)
                      for i in range(self.n)]
        self.faults = list(faults or [])
        self.sync_count = -1
        self.dead = np.zeros(self.n, dtype=bool)
        self.drop_until = np.full(self.n, -1, dtype=int)
        self.bus_off = False
        self.emcy_out: list[tuple[int, int]] = []      # (drive, code) raised since the last take_emcy()
        self.lock = threading.RLock()
        self.tau = np.zeros(self.n)
        self.last_sensors = None
        self.pending: list[tuple | None] = [None] * self.n   # RPDO data received since the last SYNC

    def inject(self, fault: Fault | str) -> None:
        if isinstance(fault, str):
            fault = Fault.parse(fault)
        if fault.drive is not None and not 0 <= fault.drive < self.n:
            raise ConfigError(None, "fault", f"drive index {fault.drive} out of range 0..{self.n - 1}")
        with self.lock:
            self.faults.append(fault)

    def take_emcy(self) -> list[tuple[int, int]]:
        with self.lock:
            out, self.emcy_out = self.emcy_out, []
        return out

    def _raise(self, i: int, code: int) -> None:
        if self.cores[i].fault(code):
            self.emcy_out.append((i, code))

    def heartbeat_lost(self, i: int | None = None) -> list[int]:
        """The master's heartbeat stopped (consumer timeout): quick stop and EMCY 0x8130 for every enabled drive.
        Returns the drives that were stopped."""
        stopped = []
        with self.lock:
            for k in range(self.n) if i is None else [i]:
                if not self.dead[k] and self.cores[k].quick_stop():
                    self.emcy_out.append((k, EMCY_HEARTBEAT))
                    stopped.append(k)
        return stopped

    def _apply_faults(self, k: int) -> None:
        keep = []
        for f in self.faults:
            if f.at_cycle > k:
                keep.append(f)
                continue
            if f.kind == "dead_node":
                self.dead[f.drive] = True
            elif f.kind == "lost_frames":
                self.drop_until[f.drive] = max(self.drop_until[f.drive], k + f.count - 1)
            elif f.kind == "drive_fault":
                self._raise(f.drive, f.code)
            elif f.kind == "bus_error":
                self.bus_off = True
            elif f.kind == "heartbeat_loss":
                for i in range(self.n) if f.drive is None else [f.drive]:
                    if self.cores[i].quick_stop():
                        self.emcy_out.append((i, EMCY_HEARTBEAT))
        self.faults = keep

    def on_sync(self, step: bool = True, duration: float | None = None):
        """One SYNC. Returns per drive (statusword, counts, current per-mille) or None if that TPDO is not sent."""
        with self.lock:
            self.sync_count += 1
            k = self.sync_count
            if self.faults:
                self._apply_faults(k)
            s = self.plant.read_sensors()
            self.last_sensors = s
            counts = np.asarray(s.encoder_counts, dtype=np.int64)
            cur = np.rint(np.asarray(s.motor_current, dtype=float) * 1000.0 / np.asarray(
                self.robot.drives.rated_current, dtype=float)).astype(np.int64)
            cur = np.clip(cur, -32768, 32767)
            out = []
            for i, c in enumerate(self.cores):
                c.update_velocity(int(counts[i]))
                if self.dead[i] or self.bus_off or k <= self.drop_until[i]:
                    out.append(None)
                else:
                    out.append((c.statusword(), int(counts[i]), int(cur[i])))
            for i, p in enumerate(self.pending):   # synchronous RPDOs take effect at this SYNC
                if p is not None:
                    self._apply(i, *p)
            self.pending = [None] * self.n
            tau = np.zeros(self.n)
            for i, c in enumerate(self.cores):
                if self.dead[i]:   # a dead drive: no power, the spring-applied brake holds
                    tau[i] = float(np.clip(c.hold_torque(), -c.brake_torque, c.brake_torque))
                    continue
                tau[i], code = c.torque(int(counts[i]))
                if code is not None:
                    self.emcy_out.append((i, code))
            self.tau = tau
            if step:
                self.plant.step(tau, self.dt if duration is None else duration)
            return out

    # -- RPDO / SDO side (device units) ---------------------------------------------------------------
    def latch_command(self, i: int, controlword: int | None, torque_permille: int | None,
                      velocity_counts: int | None = None) -> None:
        """RPDO received: takes effect at the next SYNC (a later RPDO before that SYNC overwrites it)."""
        with self.lock:
            old = self.pending[i]
            if old is not None:
                controlword = old[0] if controlword is None else controlword
                torque_permille = old[1] if torque_permille is None else torque_permille
                velocity_counts = old[2] if velocity_counts is None else velocity_counts
            self.pending[i] = (controlword, torque_permille, velocity_counts)

    def apply_now(self, i: int, controlword: int | None, torque_permille: int | None,
                  velocity_counts: int | None = None) -> None:
        """SDO write of 0x6040/0x6071/0x60FF: effective immediately."""
        with self.lock:
            self._apply(i, controlword, torque_permille, velocity_counts)

    def _apply(self, i: int, controlword, torque_permille, velocity_counts) -> None:
            if self.dead[i]:
                return
            c = self.cores[i]
            if torque_permille is not None:
                c.target_torque = int(torque_permille)
            if velocity_counts is not None:
                c.target_velocity = int(velocity_counts)
            if controlword is not None:
                c.on_controlword(int(controlword))
