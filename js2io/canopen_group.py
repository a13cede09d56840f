"""CanopenDriveGroup: n CiA 402 drives on a python-can bus through the `canopen` stack.

canopen does NMT, SDO configuration, EMCY decoding and receives heartbeats; the cyclic path bypasses its per-PDO
machinery: RPDOs are packed with `struct` and sent as raw frames, TPDOs are raw subscriptions unpacked with `struct`
(canopen's PdoMap/Variable layers cost more than the whole cycle budget at 500 Hz; see docs/acquisition.md).

PDO layout: the EDS's default PDO configuration (`js2io.pdo.read_layout`), written by SDO at every start, never
assumed. With configs/js2/drives.eds:
  RPDO1 0x200+id, sync (type 1): 0x6040 controlword U16, 0x6071 target torque I16 (per-mille of 0x6076)
  RPDO2 0x300+id, sync:          0x60FF target velocity I32 (increments/s; sent only in CSV)
  TPDO1 0x180+id, every SYNC:    0x6041 statusword U16, 0x6064 position actual I32, 0x6078 current actual I16
  TPDO2 off
Heartbeats both ways: the drives produce every heartbeat_ms (0x1017) and consume the master's (0x1016, 3x);
the master watches theirs (canopen has no consumer timeout, so this class does it).
"""
from __future__ import annotations

import logging
import os
import threading
import time

import can
import canopen
import numpy as np

from js2spec.errors import ConfigError, Js2Error

from . import cia402
from .group import DriveEvent, DriveGroup, RawFeedback, motor_position_limits_counts
from .pdo import (CONTROLWORD, CURRENT_ACTUAL, POSITION_ACTUAL, STATUSWORD, TARGET_TORQUE, TARGET_VELOCITY,
                  read_layout)

log = logging.getLogger(__name__)


class BusError(Js2Error):
    pass


class _ErrorFrameListener(can.Listener):
    def __init__(self, group):
        self.group = group

    def on_message_received(self, msg):
        if msg.is_error_frame:
            self.group.push_event(DriveEvent("fault", f"bus error: error frame received (id 0x{msg.arbitration_id:X})"))

    def stop(self):
        pass


class CanopenDriveGroup(DriveGroup):
    def __init__(self, drives, network: canopen.Network, eds_path, *, cycle_hz: float | None = None,
                 realtime: bool = False, lockstep_timeout_s: float = 0.5, master_node_id: int = 0x7F,
                 sdo_timeout_s: float = 0.5, pump: bool = True, sync: str = "auto"):
        """sync (real time only): 'master' -- the cycle loop sends each SYNC at its deadline; 'periodic' -- python-can's
        periodic send produces SYNC (kernel-timed by the broadcast manager on SocketCAN; a thread elsewhere) and the
        loop only has to be ready before each one: a late loop costs a stale cycle, never a late SYNC;
        'auto' -- periodic on SocketCAN, master otherwise."""
        super().__init__(drives, cycle_hz)
        if sync not in ("auto", "master", "periodic"):
            raise ValueError(f"sync={sync!r}: auto, master or periodic")
        self.sync_mode = sync
        self._sync_task = None
        self._spin = None       # set when the loop starts (the scheduling class is chosen before)
        self.network = network
        self.eds_path = str(eds_path)
        self.node_ids = [int(x) for x in (drives.node_ids or range(1, self.n + 1))]
        self.realtime = realtime
        self.lockstep_timeout_s = lockstep_timeout_s
        self.master_node_id = master_node_id
        self.sdo_timeout_s = sdo_timeout_s
        # pump: during the cycle loop the main thread reads the bus itself (canopen's notifier thread is paused;
        # heartbeats and EMCY are dispatched to canopen inline) -- no thread hand-off per TPDO, no GIL ping-pong
        self.pump = pump
        self._paused = False
        self.hb_ms = float(drives.heartbeat_ms or 100.0)
        self.nodes: list[canopen.RemoteNode] = []
        self.layout = read_layout(self.eds_path)
        fb = self.layout.feedback
        self._fb_codec = fb.codec
        self._fb_size = fb.codec.size
        self._fb_pos = tuple(fb.objects.index(o) for o in (STATUSWORD, POSITION_ACTUAL, CURRENT_ACTUAL))
        self._index = {fb.cob_id(nid): i for i, nid in enumerate(self.node_ids)}
        # per RPDO: (codec, which value goes where: 0 controlword, 1 torque, 2 velocity), messages per drive
        slot = {CONTROLWORD: 0, TARGET_TORQUE: 1, TARGET_VELOCITY: 2}
        self._rpdos = []
        for p in self.layout.rpdos:
            if any(o not in slot for o in p.objects):
                raise ConfigError(self.eds_path, None, f"{p.name} maps objects other than 0x6040/0x6071/0x60FF "
                                  f"({', '.join(f'0x{o:04X}' for o in p.objects)}); the master fills only those")
            self._rpdos.append((p.codec, tuple(slot[o] for o in p.objects), TARGET_VELOCITY in p.objects,
                                [can.Message(arbitration_id=p.cob_id(nid), data=bytes(p.codec.size),
                                             is_extended_id=False) for nid in self.node_ids]))
        self._status = np.zeros(self.n, dtype=np.int64)
        self._counts = np.zeros(self.n, dtype=np.int64)
        self._cur = np.zeros(self.n, dtype=np.int64)
        self._got = np.zeros(self.n, dtype=bool)
        self._ngot = 0
        self._nexpect = self.n
        self._expect = np.ones(self.n, dtype=bool)   # drives whose TPDO the cycle waits for
        self._miss = np.zeros(self.n, dtype=int)
        self._done = threading.Event()
        self._t_done = 0.0
        self._hb_time = [None] * self.n
        self._hb_state = [None] * self.n
        self._hb_reported = [False] * self.n
        self._hb_task = None
        self._t0 = None
        self._next = None
        self.missed = 0                 # real time: SYNCs sent later than one period after their deadline
        self.late_tpdos = 0             # TPDOs that arrived after their cycle was closed (dropped)
        self.sync_times: list[float] = []
        self.round_trips: list[float] = []     # s from SYNC to the last TPDO of the cycle (nan: incomplete)
        self.keep_sync_times = False
        self._opened = False
        self.warnings: list[str] = []
        self.source_detail = "hardware"
        self._sync_msg = can.Message(arbitration_id=self.layout.sync_cob, data=b"", is_extended_id=False)

    # ------------------------------------------------------------------ set-up
    def _sdo_write(self, i, index, sub, value):
        node = self.nodes[i]
        try:
            if sub is None:
                node.sdo[index].raw = value
            else:
                node.sdo[index][sub].raw = value
        except canopen.SdoAbortedError as e:
            raise Js2Error(f"node {self.node_ids[i]}: SDO write 0x{index:04X}{'' if sub is None else f':{sub}'} = "
                           f"{value} refused ({e}); check that the drive supports this object") from None
        except canopen.SdoCommunicationError as e:
            raise Js2Error(f"node {self.node_ids[i]}: no SDO answer writing 0x{index:04X} ({e}); check that the drive "
                           f"is powered, its node-id and the bitrate") from None

    def _sdo_read(self, i, index, sub=None):
        node = self.nodes[i]
        try:
            return node.sdo[index].raw if sub is None else node.sdo[index][sub].raw
        except canopen.SdoAbortedError as e:
            raise Js2Error(f"node {self.node_ids[i]}: SDO read 0x{index:04X} refused ({e})") from None
        except canopen.SdoCommunicationError as e:
            raise Js2Error(f"node {self.node_ids[i]}: no SDO answer reading 0x{index:04X} ({e}); check that the drive "
                           f"is powered, its node-id ({self.node_ids[i]}), the bus and the bitrate") from None

    def _optional(self, i, index, sub, value):
        """A write some drives refuse (object absent): warn, go on."""
        try:
            self._sdo_write(i, index, sub, value)
        except Js2Error as e:
            if "no SDO answer" in str(e):
                raise
            log.warning("%s (optional object, continuing)", e)
            self.warnings.append(str(e))

    def _map(self, i, comm, mapping, cob, entries, trans_type=1, enable=True):
        self._sdo_write(i, comm, 1, cob | 0x80000000)          # disable while mapping
        self._sdo_write(i, mapping, 0, 0)
        for k, e in enumerate(entries, start=1):
            self._sdo_write(i, mapping, k, e)
        self._sdo_write(i, mapping, 0, len(entries))
        self._sdo_write(i, comm, 2, trans_type)
        self._sdo_write(i, comm, 1, cob if enable else cob | 0x80000000)

    def open(self) -> None:
        net = self.network
        if net.bus is None:
            raise Js2Error("CANopen network has no bus: connect it first")
        for nid in self.node_ids:
            node = canopen.RemoteNode(nid, self.eds_path)
            node.sdo.RESPONSE_TIMEOUT = self.sdo_timeout_s
            net.add_node(node)
            self.nodes.append(node)
        if net.notifier is not None:
            net.notifier.add_listener(_ErrorFrameListener(self))
        net.send_message(0x000, bytes([0x80, 0]))      # NMT: all to pre-operational (PDOs off)
        time.sleep(0.02)
        lo, hi = motor_position_limits_counts(self.drives, self.scaling)
        period_ms = 1000.0 / self.cycle_hz
        names = []
        for i, nid in enumerate(self.node_ids):
            names.append(str(self._sdo_read(i, 0x1008)))
            modes = int(self._sdo_read(i, 0x6502))
            if not modes & (1 << 9):
                raise Js2Error(f"node {nid}: cyclic synchronous torque (mode 10) not supported (0x6502 = 0x{modes:08X})")
            rt = int(self._sdo_read(i, 0x6076))
            rc = int(self._sdo_read(i, 0x6075))
            want_t, want_c = self.scaling.rated_torque_mnm()[i], self.scaling.rated_current_ma()[i]
            if abs(rt - want_t) > 0.005 * want_t or abs(rc - want_c) > 0.005 * want_c:
                raise ConfigError(self.drives.source, "rated_torque",
                                  f"node {nid} reports rated torque {rt} mN*m / rated current {rc} mA (0x6076/0x6075) "
                                  f"but drives.yaml says {want_t} mN*m / {want_c} mA; fix drives.yaml")
            self._sdo_write(i, 0x6040, None, 0)                              # disable voltage
            self._sdo_write(i, 0x6072, None, int(self.limit_permille[i]))    # max torque: the hard limit
            if int(self._sdo_read(i, 0x6072)) != int(self.limit_permille[i]):
                raise Js2Error(f"node {nid}: max torque 0x6072 did not take the value {self.limit_permille[i]}")
            self._sdo_write(i, 0x607D, 1, int(lo[i]))
            self._sdo_write(i, 0x607D, 2, int(hi[i]))
            self._optional(i, 0x605A, None, 6)                               # quick stop: ramp, stay (hold)
            if period_ms == int(period_ms):
                self._optional(i, 0x60C2, 1, int(period_ms))                 # interpolation period = SYNC
                self._optional(i, 0x60C2, 2, -3)
            for p in self.layout.rpdos + self.layout.tpdos:                  # the EDS's layout
                self._map(i, p.comm, p.mapping, p.cob_id(nid), list(p.entries), trans_type=p.transmission)
            for comm, cob_base in self.layout.disabled:                      # the PDOs it leaves off
                self._sdo_write(i, comm, 1, 0x80000000 | (cob_base + nid))
            self._sdo_write(i, 0x6060, None, int(self.modes[i]))
            self._sdo_write(i, 0x1016, 1, (self.master_node_id << 16) | int(3 * self.hb_ms))
            self._sdo_write(i, 0x1017, None, int(self.hb_ms))
            node = self.nodes[i]
            node.nmt.add_heartbeat_callback(lambda state, i=i: self._on_heartbeat(i, state))
            node.emcy.add_callback(lambda err, i=i: self._on_emcy(i, err))
            net.subscribe(self.layout.feedback.cob_id(nid), self._on_tpdo)
        self.source_detail = "hil_sim:canopen" if all(n.startswith("js2-hil_sim") for n in names) else "hardware"
        self.source = "hil_sim" if self.source_detail.startswith("hil_sim") else "hardware"
        if self.source == "hardware" and not self.realtime:
            # lock-step would send SYNC as fast as real drives answer, and t = cycle / cycle_hz would be false
            self.realtime = True
            log.warning("drives on this bus are not the js2 simulator (0x1008 = %r): SYNC paced by the wall clock "
                        "(--realtime)", names[0])
        self._hb_task = net.send_periodic(0x700 + self.master_node_id, bytes([5]), self.hb_ms / 1000.0)
        net.send_message(0x000, bytes([0x01, 0]))      # NMT: start all
        for i in range(self.n):                        # modes verified on 0x6061
            m = int(self._sdo_read(i, 0x6061))
            if m != int(self.modes[i]):
                raise Js2Error(f"node {self.node_ids[i]}: mode display 0x6061 = {m}, expected {self.modes[i]}")
        deadline = time.monotonic() + 3 * self.hb_ms / 1000.0 + 0.5
        while time.monotonic() < deadline and any(s != 5 for s in self._hb_state):
            time.sleep(0.01)
        missing = [self.node_ids[i] for i, s in enumerate(self._hb_state) if s != 5]
        if missing:
            raise Js2Error(f"nodes {missing} sent no heartbeat in OPERATIONAL state after NMT start "
                           f"(within {3 * self.hb_ms:g} ms); check them")
        self._opened = True
        if self.pump:
            self._pause_notifier()

    def _pause_notifier(self) -> None:
        net = self.network
        if net.notifier is not None and not self._paused:
            net.notifier.stop(1.0)
            net.check()
            net.notifier = None
            self._paused = True

    def _resume_notifier(self) -> None:
        net = self.network
        if self._paused:
            net.notifier = can.Notifier(net.bus, net.listeners, net.NOTIFIER_CYCLE)
            net.notifier.add_listener(_ErrorFrameListener(self))
            self._paused = False

    def _dispatch(self, msg) -> None:
        if msg.is_error_frame:
            self.push_event(DriveEvent("fault", f"bus error: error frame received (id 0x{msg.arbitration_id:X})"))
            return
        if msg.is_remote_frame:
            return
        cid = msg.arbitration_id
        if cid in self._index:
            self._on_tpdo(cid, msg.data, msg.timestamp)
        else:
            self.network.notify(cid, msg.data, msg.timestamp)

    def _wait_tpdos(self, deadline: float) -> None:
        if not self._paused:
            self._done.wait(max(deadline - time.perf_counter(), 0.0))
            return
        bus = self.network.bus
        while not self._done.is_set():
            rem = deadline - time.perf_counter()
            if rem <= 0:
                break
            msg = bus.recv(rem)
            if msg is None:
                break
            self._dispatch(msg)
        self._drain()

    def _drain(self, drop_tpdo: bool = False) -> None:
        """Dispatch what is already waiting (EMCY, heartbeats) without blocking. Before a SYNC, TPDOs still in the
        queue are late answers to the previous SYNC: dropped (counted), never taken for the new cycle."""
        if not self._paused:
            return
        bus = self.network.bus
        for _ in range(256):
            msg = bus.recv(0)
            if msg is None:
                break
            if drop_tpdo and msg.arbitration_id in self._index and not msg.is_error_frame:
                self.late_tpdos += 1
                continue
            self._dispatch(msg)

    # ------------------------------------------------------------------ callbacks (notifier thread)
    def _on_tpdo(self, can_id, data, timestamp):
        i = self._index[can_id]
        if len(data) < self._fb_size:
            return
        v = self._fb_codec.unpack_from(data)
        a, b, c = self._fb_pos
        self._status[i], self._counts[i], self._cur[i] = v[a], v[b], v[c]
        if not self._got[i]:
            self._got[i] = True
            if self._expect[i]:
                self._ngot += 1
                if self._ngot >= self._nexpect:
                    self._t_done = time.perf_counter()
                    self._done.set()

    def _on_heartbeat(self, i, state):
        self._hb_time[i] = time.monotonic()
        prev = self._hb_state[i]
        self._hb_state[i] = state
        if self._opened and state != 5 and prev == 5:
            self.push_event(DriveEvent("fault", f"node {self.node_ids[i]} (drive {i}) left OPERATIONAL "
                                       f"(heartbeat state {state})", joint=i))

    def _on_emcy(self, i, err):
        code = int(err.code)
        desc = cia402.EMCY_NAMES.get(code) or err.get_desc() or "error"   # the project's specific names first
        fatal = code != 0
        self.push_event(DriveEvent("emcy", f"EMCY node {self.node_ids[i]} (drive {i}): 0x{code:04X} {desc} "
                                   f"(error register 0x{err.register:02X})", joint=i, fatal=fatal, code=code))

    # ------------------------------------------------------------------ the cycle
    def _send(self, msg):
        with self.network.send_lock:
            self.network.bus.send(msg)

    def _transmit(self, controlword, torque_permille, velocity_counts) -> None:
        cw, tq = controlword.tolist(), torque_permille.tolist()
        vel = velocity_counts.tolist() if velocity_counts is not None else None
        for codec, slots, has_velocity, msgs in self._rpdos:
            if has_velocity and vel is None:
                continue          # the velocity RPDO goes out only while a drive is in CSV
            for i in range(self.n):
                row = (cw[i], tq[i], vel[i] if vel is not None else 0)
                m = msgs[i]
                m.data = bytearray(codec.pack(*[row[s] for s in slots]))
                self._send(m)

    def _sync(self) -> RawFeedback:
        self.network.check()          # re-raise what killed the receive thread (bus errors)
        self._got[:] = False
        self._ngot = 0
        # lock-step: a drive that missed 3 cycles in a row is not waited for (still read when it answers). Real time:
        # every drive is waited for up to the deadline (the time is the period's anyway): not waiting would drop its
        # late answers before every SYNC and leave its feedback stale for good
        self._expect = self._miss < 3 if not self.realtime else np.ones(self.n, dtype=bool)
        self._nexpect = int(self._expect.sum())
        self._done.clear()
        if self._nexpect == 0:
            self._done.set()
        if self._spin is None:
            self._spin = _spin_s()
        now = time.perf_counter()
        if self.realtime and self._periodic():
            t = self._sync_periodic(now)
        elif self.realtime:
            if self._next is None:
                self._t0 = self._next = now
            else:
                self._next += self.dt
                delay = self._next - now
                if delay > 0:
                    _sleep_until(self._next, self._spin)
                elif delay < -self.dt:
                    # overrun by more than a period: skip the lost deadlines (counted) and re-anchor, rather than
                    # a catch-up burst of SYNCs that the drives cannot answer in time
                    skipped = int(-delay / self.dt)
                    self.missed += skipped
                    self._next += skipped * self.dt
            self._drain(drop_tpdo=True)
            t_sync = time.perf_counter()
            self._send(self._sync_msg)
            if self.keep_sync_times:
                self.sync_times.append(t_sync)
            self._wait_tpdos(self._next + self.dt * 0.9)
            if self.keep_sync_times:
                self.round_trips.append(self._t_done - t_sync if self._done.is_set() else float("nan"))
            t = t_sync - self._t0
        else:
            self._drain(drop_tpdo=True)
            self._send(self._sync_msg)
            self._wait_tpdos(time.perf_counter() + self.lockstep_timeout_s)
            t = None
        self._check_heartbeats()
        self._miss = np.where(self._got, 0, self._miss + 1)
        return RawFeedback(self._status.copy(), self._counts.copy(), self._cur.copy(), self._got.copy(), t)

    def _periodic(self) -> bool:
        if self.sync_mode == "auto":
            self.sync_mode = "periodic" if type(self.network.bus).__name__ == "SocketcanBus" else "master"
        return self.sync_mode == "periodic"

    def _sync_periodic(self, now: float) -> float:
        """Cycle k with SYNC produced by python-can's periodic task started at t0: be ready just before t0 + k*dt
        (late TPDOs of the previous SYNC dropped), then collect the TPDOs until 0.9 period after it."""
        if self._sync_task is None:
            self._drain(drop_tpdo=True)
            self._t0 = self._next = time.perf_counter()
            with self.network.send_lock:
                self._sync_task = self.network.bus.send_periodic(self._sync_msg, self.dt)
        else:
            self._next += self.dt
            margin = min(5e-5, 0.05 * self.dt)
            delay = self._next - now
            if delay > margin:
                _sleep_until(self._next - margin, self._spin)
                self._drain(drop_tpdo=True)
            elif delay >= -0.9 * self.dt:
                # this SYNC is out (or about to be) before the command was: the drives apply it one SYNC later
                # (counted); its answers may be queued already, so nothing is dropped
                self.missed += 1
            else:
                # the loop was not back before this SYNC's answers were due: those SYNCs went out anyway (the drives
                # applied the last command again); skip to the next one that is still ahead (counted)
                skipped = int(-delay / self.dt) + 1
                self.missed += skipped
                self._next += skipped * self.dt
                _sleep_until(self._next - margin, self._spin)
                self._drain(drop_tpdo=True)
        if self.keep_sync_times:
            self.sync_times.append(self._next)
        self._wait_tpdos(self._next + self.dt * 0.9)
        if self.keep_sync_times:
            self.round_trips.append(self._t_done - self._next if self._done.is_set() else float("nan"))
        return self._next - self._t0

    def _check_heartbeats(self) -> None:
        now = time.monotonic()
        lim = 3 * self.hb_ms / 1000.0
        for i in range(self.n):
            t = self._hb_time[i]
            if t is not None and now - t > lim and not self._hb_reported[i]:
                self._hb_reported[i] = True
                self.push_event(DriveEvent("fault", f"node {self.node_ids[i]} (drive {i}): heartbeat lost "
                                           f"(none for {1000 * (now - t):.0f} ms, limit {1000 * lim:.0f} ms)", joint=i))

    def _set_modes(self, modes) -> None:
        paused = self._paused
        self._resume_notifier()          # SDO needs the receive thread
        try:
            self._set_modes_sdo(modes)
        finally:
            if paused:
                self._pause_notifier()

    def _set_modes_sdo(self, modes) -> None:
        for i in range(self.n):
            self._sdo_write(i, 0x6060, None, int(modes[i]))
            m = int(self._sdo_read(i, 0x6061))
            if m != int(modes[i]):
                raise Js2Error(f"node {self.node_ids[i]}: mode {modes[i]} not taken (0x6061 = {m})")

    def stop_sync(self) -> None:
        if self._sync_task is not None:
            try:
                self._sync_task.stop()
            except Exception:   # noqa: BLE001 - the bus may be gone
                pass
            self._sync_task = None

    def stop_heartbeat(self) -> None:
        """Stop the master heartbeat producer (tests: the drives must quick-stop)."""
        if self._hb_task is not None:
            self._hb_task.stop()
            self._hb_task = None

    def close(self) -> None:
        self.stop_sync()
        try:
            self.stop_heartbeat()
            if self.network.bus is not None and self._opened:
                self.network.send_message(0x000, bytes([0x80, 0]))   # pre-operational: PDOs off
        except Exception:
            pass
        self._opened = False


SPIN_S = 0.0003     # normal scheduling: time.sleep overshoots ~0.1 ms
SPIN_FIFO_S = 0.0001   # SCHED_FIFO wakes within ~10 us: spin less, leave the core to the others


def _spin_s() -> float:
    try:
        return SPIN_FIFO_S if os.sched_getscheduler(0) == os.SCHED_FIFO else SPIN_S
    except (AttributeError, OSError):
        return SPIN_S


def _sleep_until(t_target: float, spin_s: float | None = None) -> None:
    """Sleep to just before the deadline, then spin the last `spin_s` (default: by the scheduling class)."""
    spin = _spin_s() if spin_s is None else spin_s
    while True:
        d = t_target - time.perf_counter()
        if d <= 0:
            return
        if d > spin + 0.0001:
            time.sleep(d - spin)
