"""The simulated drives and a CANopen master in one process, on python-can's `virtual` bus (what js2-acquire does
when given no bus options; also the fixture of the acquisition tests).

    with InProcessCanopen(robot, faults=["drive_fault:2@300"]) as rig:
        run_trials(rig.group, robot, ["static"], "x.mcap")
"""
from __future__ import annotations

import os
import time

import canopen

from hil_sim.drives import CanopenSimulator
from js2io.bus import open_bus
from js2io.canopen_group import CanopenDriveGroup
from js2spec.errors import Js2Error


def close_master(group, network) -> None:
    """The master's side of a rig, closed in order: the drive group (its own safe stop), then the CANopen network
    (whose bus may be gone already with a simulator that ended)."""
    if group is not None:
        group.close()
    if network is not None:
        try:
            network.disconnect()
        except Exception:   # noqa: BLE001 - the other side may be gone already
            pass


class InProcessCanopen:
    def __init__(self, robot, *, cycle_hz: float | None = None, seed: int = 0, faults=None, realtime: bool = False,
                 sim_realtime: bool | None = None, q0=None, lockstep_timeout_s: float = 0.5):
        self.robot = robot
        self.channel = f"js2-{os.getpid()}-{time.monotonic_ns()}"
        cycle_hz = cycle_hz or robot.drives.cycle_hz or 500.0
        self.sim = CanopenSimulator(robot, bus_kwargs={"interface": "virtual", "channel": self.channel},
                                    cycle_hz=cycle_hz, seed=seed, faults=faults,
                                    realtime=realtime if sim_realtime is None else sim_realtime, q0=q0)
        self.bus = None
        self.network = None
        self.group = None
        self._cycle_hz = cycle_hz
        self._realtime = realtime
        self._timeout = lockstep_timeout_s

    def start(self) -> "InProcessCanopen":
        if self.robot.eds_path is None:
            raise Js2Error(f"{self.robot.folder}: no drives.eds (the drives' object dictionary); add it")
        self.sim.start()
        self.bus = open_bus({"interface": "virtual", "channel": self.channel})
        self.network = canopen.Network(self.bus)
        self.network.connect()
        self.group = CanopenDriveGroup(self.robot.drives, self.network, self.robot.eds_path, cycle_hz=self._cycle_hz,
                                       realtime=self._realtime, lockstep_timeout_s=self._timeout)
        return self

    def close(self) -> None:
        close_master(self.group, self.network)
        self.sim.stop()

    def __enter__(self):
        return self.start()

    def __exit__(self, *exc):
        self.close()
