"""Six (n) simulated CiA 402 drives as CANopen slaves: `canopen.LocalNode`s built from configs/<robot>/drives.eds.

What a master sees is what a real drive would show: NMT (boot-up, pre-operational/operational), SDO access to the
object dictionary (0x6072 max torque, 0x607D software limits, 0x6060/0x6061 modes, 0x6075/0x6076 ratings,
0x603F error code, PDO communication/mapping parameters), synchronous PDOs packed from the mapping the master
wrote, heartbeat producer (0x1017) and consumer (0x1016: the master's heartbeat; on timeout a quick stop + EMCY
0x8130), EMCY on every fault. Physics: one plant period per SYNC (lock-step, deterministic) or a wall-clock
physics thread (`realtime=True`). Faults are injected with `inject()` (see drives_core.Fault).
"""
from __future__ import annotations

import logging
import struct
import threading
import time
from functools import partial

import can
import canopen
import numpy as np

from hil_sim.drives_core import Fault, SimDriveSet
from js2io.pdo import STRUCT_CODE, read_layout
from js2spec.errors import ConfigError

log = logging.getLogger(__name__)


class CanopenSimulator:
    """The simulated drives on a python-can bus. `bus` is shared (not closed) if given, else made from bus_kwargs."""

    def __init__(self, robot, bus: can.BusABC | None = None, *, bus_kwargs: dict | None = None,
                 cycle_hz: float | None = None, seed: int | None = None, faults=None, realtime: bool = False,
                 eds_path=None, plant=None, q0=None):
        self.robot = robot
        d = robot.drives
        self.n = d.n
        self.node_ids = [int(x) for x in (d.node_ids or range(1, self.n + 1))]
        eds = eds_path or robot.eds_path
        if eds is None:
            raise ConfigError(robot.folder, None, "no drives.eds in the robot folder: the simulated drives need it")
        self.set = SimDriveSet(robot, plant=plant, cycle_hz=cycle_hz, seed=seed, q0=q0)
        for f in faults or []:
            self.set.inject(f)
        self.plant = self.set.plant
        self.cycle_hz = self.set.cycle_hz
        self.realtime = realtime
        self._own_bus = bus is None
        self.network = canopen.Network(bus)
        self.nodes: list[canopen.LocalNode] = []
        self._plans_dirty = [True] * self.n
        self._tpdo = [None] * self.n     # (cob_id, struct, [getters])
        self._rpdo = [[] for _ in range(self.n)]
        self._hb_consumer = [(0, 0)] * self.n   # (master node id, timeout ms)
        self._hb_last: dict[int, float] = {}
        self._hb_tripped = [False] * self.n
        self._dead_done = [False] * self.n
        self._bus_off_done = False
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []
        self.syncs = 0
        self._lock = self.set.lock
        for i, nid in enumerate(self.node_ids):
            od = canopen.import_od(str(eds), nid)
            node = canopen.LocalNode(nid, od)
            self.network.add_node(node)
            node.add_write_callback(partial(self._on_write, i))
            node.add_read_callback(partial(self._on_read, i))
            # the drive's own ratings (as on its name plate): mN*m and mA
            node.data_store.setdefault(0x6076, {})[0] = struct.pack("<I", int(round(d.rated_torque[i] * 1000)))
            node.data_store.setdefault(0x6075, {})[0] = struct.pack("<I", int(round(d.rated_current[i] * 1000)))
            self.nodes.append(node)
        self._bus_kwargs = bus_kwargs
        # which PDOs exist and where they listen: the EDS (the master writes the same layout; the frames are built
        # from the mapping it wrote)
        self.layout = read_layout(str(eds))

    # ------------------------------------------------------------------ life cycle
    def start(self) -> "CanopenSimulator":
        if self._own_bus:
            self.network.connect(**(self._bus_kwargs or {"interface": "virtual", "channel": "js2"}))
        else:
            self.network.connect()    # uses the given bus, starts the notifier
        self.network.subscribe(self.layout.sync_cob, self._on_sync)
        for i, nid in enumerate(self.node_ids):
            for k, p in enumerate(self.layout.rpdos):
                self.network.subscribe(p.cob_id(nid), partial(self._on_rpdo, i, k))
        self.network.subscribe(0x700 + 0x7F, self._on_master_heartbeat)
        for node in self.nodes:      # power-on: boot-up message, then pre-operational
            node.nmt.send_command(0x81)
            node.nmt.send_command(0x80)
        t = threading.Thread(target=self._watchdog, name="js2-sim-watchdog", daemon=True)
        t.start()
        self._threads.append(t)
        if self.realtime:
            t = threading.Thread(target=self._physics, name="js2-sim-physics", daemon=True)
            t.start()
            self._threads.append(t)
        return self

    def stop(self) -> None:
        self._stop.set()
        for node in self.nodes:
            try:
                node.nmt.stop_heartbeat()
            except Exception:
                pass
        for t in self._threads:
            t.join(timeout=1.0)
        try:
            if self._own_bus:
                self.network.disconnect()
            elif self.network.notifier is not None:
                self.network.notifier.stop(0.5)
        except Exception as e:   # pragma: no cover - shutdown noise
            log.debug("simulator shutdown: %s", e)

    def __enter__(self):
        return self.start()

    def __exit__(self, *exc):
        self.stop()

    def inject(self, fault: Fault | str) -> None:
        self.set.inject(fault)

    # ------------------------------------------------------------------ object dictionary hooks
    def _on_read(self, i, index, subindex, od):
        c = self.set.cores[i]
        if index == 0x6041:
            return c.statusword()
        if index == 0x6061:
            return c.mode_display
        if index == 0x6060:
            return c.mode
        if index == 0x603F:
            return c.error_code
        if index == 0x1001:
            return 1 if c.error_code else 0
        if index == 0x6064:
            s = self.set.last_sensors
            return int(s.encoder_counts[i]) if s is not None else 0
        if index == 0x6072:
            return c.max_torque
        return None

    def _on_write(self, i, index, subindex, od, data):
        c = self.set.cores[i]
        if 0x1400 <= index <= 0x1BFF:
            self._plans_dirty[i] = True
            return
        v = od.decode_raw(data)
        if index == 0x6040:
            self.set.apply_now(i, v, None)
        elif index == 0x6071:
            self.set.apply_now(i, None, v)
        elif index == 0x60FF:
            self.set.apply_now(i, None, None, v)
        elif index == 0x6060:
            try:
                c.set_mode(int(v))
            except ValueError:
                raise canopen.sdo.SdoAbortedError(0x06090030)  # value range exceeded
        elif index == 0x6072:
            c.max_torque = int(v)
        elif index == 0x607D:
            if subindex == 1:
                c.pos_min = int(v)
            elif subindex == 2:
                c.pos_max = int(v)
        elif index == 0x1016 and subindex == 1:
            mid = (int(v) >> 16) & 0x7F
            self._hb_consumer[i] = (mid, int(v) & 0xFFFF)
            if mid and 0x700 + mid not in self.network.subscribers:
                self.network.subscribe(0x700 + mid, self._on_master_heartbeat)

    def _u32(self, node, index, sub) -> int:
        return struct.unpack("<I", node.get_data(index, sub))[0]

    def _build_plans(self, i: int) -> None:
        node = self.nodes[i]
        od = node.object_dictionary

        def entries(map_index):
            count = node.get_data(map_index, 0)[0]
            out = []
            for k in range(1, count + 1):
                e = self._u32(node, map_index, k)
                idx, sub = e >> 16, (e >> 8) & 0xFF
                obj = od[idx] if sub == 0 and not isinstance(od[idx], (canopen.objectdictionary.ODRecord,
                                                                       canopen.objectdictionary.ODArray)) else od[idx][sub]
                out.append((idx, sub, STRUCT_CODE[obj.data_type]))
            return out

        fb = self.layout.feedback
        cob = self._u32(node, fb.comm, 1)
        tpdo = None
        if not cob & 0x80000000:
            ent = entries(fb.mapping)
            tpdo = (cob & 0x7FF, struct.Struct("<" + "".join(f for _, _, f in ent)), [e[0] for e in ent])
        self._tpdo[i] = tpdo
        rp = []
        for comm, mp in ((p.comm, p.mapping) for p in self.layout.rpdos):
            cob = self._u32(node, comm, 1)
            if cob & 0x80000000:
                rp.append(None)
                continue
            ent = entries(mp)
            rp.append((struct.Struct("<" + "".join(f for _, _, f in ent)), [e[0] for e in ent]))
        self._rpdo[i] = rp
        self._plans_dirty[i] = False

    # ------------------------------------------------------------------ cyclic
    def _operational(self, i: int) -> bool:
        return self.nodes[i].nmt._state == 5

    def _on_rpdo(self, i, which, can_id, data, timestamp):
        if not self._operational(i) or self.set.dead[i] or self.set.bus_off:
            return
        if self._plans_dirty[i]:
            self._build_plans(i)
        plan = self._rpdo[i][which] if which < len(self._rpdo[i]) else None
        if plan is None:
            return
        st, idxs = plan
        if len(data) < st.size:
            return
        vals = dict(zip(idxs, st.unpack_from(data)))
        self.set.latch_command(i, vals.get(0x6040), vals.get(0x6071), vals.get(0x60FF))
        if 0x6060 in vals:
            self.set.cores[i].set_mode(int(vals[0x6060]))

    def _on_sync(self, can_id, data, timestamp):
        out = self.set.on_sync(step=not self.realtime)
        self.syncs += 1
        self._handle_faults()
        bus = self.network.bus
        s = self.set.last_sensors
        for i, o in enumerate(out):
            if o is None or not self._operational(i):
                continue
            if self._plans_dirty[i]:
                self._build_plans(i)
            plan = self._tpdo[i]
            if plan is None:
                continue
            cob, st, idxs = plan
            sw, counts, cur = o
            c = self.set.cores[i]
            vals = []
            for idx in idxs:
                if idx == 0x6041:
                    vals.append(sw)
                elif idx == 0x6064:
                    vals.append(counts)
                elif idx == 0x6078:
                    vals.append(cur)
                elif idx == 0x6077:
                    vals.append(int(round(float(s.tau_motor[i]) * 1000.0 / c.rated_torque)))
                elif idx == 0x606C:
                    vals.append(int(round(c.velocity * c.cpr / (2 * np.pi))))
                elif idx == 0x6061:
                    vals.append(c.mode_display)
                else:
                    vals.append(0)
            with self.network.send_lock:
                bus.send(can.Message(arbitration_id=cob, data=st.pack(*vals), is_extended_id=False))
        self._send_emcy()

    def _send_emcy(self) -> None:
        for i, code in self.set.take_emcy():
            try:
                self.nodes[i].emcy.send(code, 0x01, b"")
            except Exception as e:  # pragma: no cover
                log.warning("EMCY send failed: %s", e)

    def _handle_faults(self) -> None:
        for i in range(self.n):
            if self.set.dead[i] and not self._dead_done[i]:
                self._dead_done[i] = True
                node = self.nodes[i]
                node.nmt.stop_heartbeat()
                self.network.unsubscribe(node.sdo.rx_cobid)
        if self.set.bus_off and not self._bus_off_done:
            self._bus_off_done = True
            try:   # the controller reports the error, then goes bus-off: silence
                self.network.bus.send(can.Message(arbitration_id=0x20000080, is_error_frame=True, is_extended_id=True,
                                                  data=bytes([0, 0, 0, 0, 0, 0, 0, 0])))
            except Exception:
                pass
            for node in self.nodes:
                node.nmt.stop_heartbeat()
                self.network.unsubscribe(node.sdo.rx_cobid)

    # ------------------------------------------------------------------ heartbeat consumer
    def _on_master_heartbeat(self, can_id, data, timestamp):
        self._hb_last[can_id - 0x700] = time.monotonic()
        for i in range(self.n):
            self._hb_tripped[i] = False

    def _watchdog(self) -> None:
        while not self._stop.wait(0.02):
            now = time.monotonic()
            for i in range(self.n):
                mid, ms = self._hb_consumer[i]
                if ms <= 0 or mid not in self._hb_last or self._hb_tripped[i]:
                    continue
                if now - self._hb_last[mid] > ms / 1000.0:
                    self._hb_tripped[i] = True
                    if self.set.heartbeat_lost(i):
                        log.warning("drive %d: master heartbeat lost (> %d ms) while enabled: quick stop", i, ms)
            with self._lock:
                self._send_emcy()

    # ------------------------------------------------------------------ wall-clock physics
    def _physics(self) -> None:
        dt = self.set.dt
        nxt = time.perf_counter()
        while not self._stop.is_set():
            nxt += dt
            delay = nxt - time.perf_counter()
            if delay > 0:
                time.sleep(delay)
            elif delay < -0.1:
                nxt = time.perf_counter()   # far behind: do not try to catch up
            with self._lock:
                self.plant.step(self.set.tau, dt)
