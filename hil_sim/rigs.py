"""The simulated rigs js2-acquire chooses with `--sim NAME` (entry points `js2.drive_groups`, see js2io.rigs):

  sim          the six simulated CiA 402 drives and the master in this process, on python-can's virtual bus
  sim-direct   the simulated drives without CAN (`hil_sim.direct.DirectDriveGroup`; fastest, for log generation)
  sim-process  js2-sim in its own process (socketcand hub on 127.0.0.1), the master here over socketcand: the
               simulator never shares the master's interpreter, so a real-time measurement is the master's, as on
               hardware (the default of `js2-acquire --realtime` without a bus)
"""
from __future__ import annotations

import collections
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

from js2spec.errors import Js2Error

ROOT = Path(__file__).resolve().parents[1]


class DirectRig:
    def __init__(self, robot, *, cycle_hz=None, seed=0, faults=(), realtime=False, rt_priority=0, cpu=None):
        from hil_sim.direct import DirectDriveGroup
        self.group = DirectDriveGroup(robot, cycle_hz=cycle_hz, seed=seed, faults=list(faults or ()))
        self.where = "in-process simulator, direct (no CAN)"

    def close(self) -> None:
        self.group.close()


def direct(robot, **kw) -> DirectRig:
    return DirectRig(robot, **kw)


def in_process(robot, *, cycle_hz=None, seed=0, faults=(), realtime=False, rt_priority=0, cpu=None):
    from hil_sim.canopen_inprocess import InProcessCanopen
    rig = InProcessCanopen(robot, cycle_hz=cycle_hz, seed=seed, faults=list(faults or ()), realtime=realtime).start()
    rig.where = "in-process simulator on python-can's virtual bus"
    return rig


def _end_with_parent() -> None:
    """In the child, before exec (Linux): SIGTERM when the master's process dies, however it dies."""
    try:
        import ctypes
        ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGTERM)    # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        pass


class ProcessRig:
    """js2-sim started as a child process (its own interpreter, its own GIL), the master connected over socketcand.
    The simulator's physics advances one period per SYNC (lock-step), so missed SYNCs cost the arm nothing but time;
    what the measurement sees is the master's scheduling and the transport."""

    def __init__(self, robot, *, cycle_hz=None, seed=0, faults=(), realtime=False, rt_priority=0, cpu=None,
                 start_timeout_s: float = 30.0):
        self.robot = robot
        self.cycle_hz = float(cycle_hz or robot.drives.cycle_hz or 500.0)
        self.realtime = realtime
        cmd = [sys.executable, "-m", "hil_sim.cli", "--robot", str(robot.folder), "--port", "0",
               "--cycle-hz", f"{self.cycle_hz:g}", "--seed", str(int(seed)), "--rt-priority", str(int(rt_priority))]
        for f in faults or ():
            cmd += ["--fault", str(f)]
        if cpu is not None:
            cmd += ["--cpu", str(int(cpu))]
        self.cmd = cmd
        self.start_timeout_s = start_timeout_s
        self.proc = None
        self.bus = self.network = self.group = None
        self.port = None
        self.tail: collections.deque[str] = collections.deque(maxlen=20)   # the child's last output lines
        self.where = ""

    def start(self) -> "ProcessRig":
        import canopen

        from js2io.bus import open_bus
        from js2io.canopen_group import CanopenDriveGroup
        self.proc = subprocess.Popen(self.cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                                     cwd=ROOT, start_new_session=True,   # Ctrl-C reaches the master only
                                     preexec_fn=_end_with_parent)
        deadline = time.monotonic() + self.start_timeout_s
        while self.port is None and time.monotonic() < deadline:
            line = self.proc.stdout.readline()
            if not line:
                break
            self.tail.append(line.rstrip())
            m = re.search(r"PORT (\d+)", line)
            if m:
                self.port = int(m.group(1))
        if self.port is None:
            self._end_child()
            last = self.tail[-1] if self.tail else "no output"
            raise Js2Error(f"the simulator process (js2-sim) did not start: {last}")
        # keep draining its output (warnings, the exit summary) so a full pipe never blocks it
        self._drainer = threading.Thread(target=self._drain, name="js2-sim-output", daemon=True)
        self._drainer.start()
        self.bus = open_bus({"interface": "socketcand", "channel": "js2", "host": "127.0.0.1", "port": self.port,
                             "tcp_tune": True})
        self.network = canopen.Network(self.bus)
        self.network.connect()
        self.group = CanopenDriveGroup(self.robot.drives, self.network, self.robot.eds_path, cycle_hz=self.cycle_hz,
                                       realtime=self.realtime)
        self.where = f"simulator in its own process (js2-sim pid {self.proc.pid}, socketcand 127.0.0.1:{self.port})"
        return self

    def _drain(self) -> None:
        for line in self.proc.stdout:
            self.tail.append(line.rstrip())

    def _end_child(self) -> None:
        if self.proc is None or self.proc.poll() is not None:
            return
        self.proc.send_signal(signal.SIGTERM)
        try:
            self.proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()

    def close(self) -> None:
        from hil_sim.canopen_inprocess import close_master

        close_master(self.group, self.network)
        self._end_child()
        if getattr(self, "_drainer", None) is not None:
            self._drainer.join(timeout=2.0)

    def summary(self) -> str:
        """The simulator's last line (SYNCs served, frames relayed, dropped)."""
        return self.tail[-1] if self.tail else ""


def own_process(robot, **kw) -> ProcessRig:
    return ProcessRig(robot, **kw).start()
