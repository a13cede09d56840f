"""DirectDriveGroup: the simulated drives and plant behind the DriveGroup interface, without CAN.

Same drive behaviour (`hil_sim.drives_core`), same device-unit quantisation and the same trial code as the
CANopen path, only much faster: for tests and benchmarks that need trial logs (identification).

    from js2spec.robot import load_robot
    from hil_sim.direct import DirectDriveGroup
    from js2io.session import run_trials
    robot = load_robot("js2")
    with DirectDriveGroup(robot, seed=0) as group:
        run_trials(group, robot, ["static", "velocity"], "out.mcap")
"""
from __future__ import annotations

import numpy as np

from js2io.group import DriveEvent, DriveGroup, RawFeedback
from hil_sim.drives_core import EMCY_NAMES, Fault, SimDriveSet


class DirectDriveGroup(DriveGroup):
    source = "hil_sim"

    def __init__(self, robot, plant=None, cycle_hz: float | None = None, seed: int | None = None,
                 faults: list[Fault | str] | None = None, q0=None):
        super().__init__(robot.drives, cycle_hz)
        self.robot = robot
        self.sim = SimDriveSet(robot, plant=plant, cycle_hz=self.cycle_hz, seed=seed, q0=q0)
        for f in faults or []:
            self.sim.inject(f)
        self.plant = self.sim.plant
        hb = float(robot.drives.heartbeat_ms or 100.0)
        self._hb_timeout_cycles = int(np.ceil(3 * hb / 1000.0 * self.cycle_hz))
        self._hb_stopped_at: int | None = None
        self._last_seen = np.zeros(self.n, dtype=int)
        self._dead_reported = np.zeros(self.n, dtype=bool)
        self._bus_reported = False
        self._opened = False
        self.source_detail = "hil_sim:direct"

    def open(self) -> None:
        from js2io.group import motor_position_limits_counts
        lo, hi = motor_position_limits_counts(self.drives, self.scaling)
        for i, c in enumerate(self.sim.cores):
            c.max_torque = int(self.limit_permille[i])
            c.pos_min, c.pos_max = int(lo[i]), int(hi[i])
            c.set_mode(int(self.modes[i]))
        self._opened = True

    def inject(self, fault: Fault | str) -> None:
        self.sim.inject(fault)

    def stop_heartbeat(self) -> None:
        """Simulate the master's heartbeat producer stopping (the drives quick-stop after 3 x heartbeat)."""
        self._hb_stopped_at = self.cycle_count

    def _transmit(self, controlword, torque_permille, velocity_counts) -> None:
        for i in range(self.n):
            self.sim.latch_command(i, int(controlword[i]), int(torque_permille[i]),
                                   None if velocity_counts is None else int(velocity_counts[i]))

    def _sync(self) -> RawFeedback:
        k = self.cycle_count + 1
        if self._hb_stopped_at is not None and k - self._hb_stopped_at == self._hb_timeout_cycles:
            self.sim.heartbeat_lost()
        out = self.sim.on_sync()
        status = np.zeros(self.n, dtype=np.int64)
        counts = np.zeros(self.n, dtype=np.int64)
        cur = np.zeros(self.n, dtype=np.int64)
        rec = np.zeros(self.n, dtype=bool)
        for i, o in enumerate(out):
            if o is not None:
                status[i], counts[i], cur[i] = o
                rec[i] = True
        alive = ~(self.sim.dead | self.sim.bus_off)
        self._last_seen[alive] = k
        for i in range(self.n):   # heartbeat consumer (sim time)
            if not alive[i] and not self._dead_reported[i] and k - self._last_seen[i] >= self._hb_timeout_cycles:
                self._dead_reported[i] = True
                self.push_event(DriveEvent("fault", f"node {self.node_id(i)} (drive {i}): heartbeat lost "
                                           f"(no heartbeat for {self._hb_timeout_cycles} cycles)", joint=i))
        if self.sim.bus_off and not self._bus_reported:
            self._bus_reported = True
            self.push_event(DriveEvent("fault", "bus error: error frame received, bus off (injected)"))
        for i, code in self.sim.take_emcy():
            self.push_event(DriveEvent("emcy", f"EMCY node {self.node_id(i)} (drive {i}): 0x{code:04X} "
                                       f"{EMCY_NAMES.get(code, 'error')}", joint=i, code=code))
        return RawFeedback(status, counts, cur, rec)

    def _set_modes(self, modes) -> None:
        for i, c in enumerate(self.sim.cores):
            c.set_mode(int(modes[i]))

    def node_id(self, i: int) -> int:
        ids = self.drives.node_ids or list(range(1, self.n + 1))
        return int(ids[i])

    def close(self) -> None:
        self._opened = False
