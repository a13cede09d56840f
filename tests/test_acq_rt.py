"""The real-time cycle's supports: the log writer thread behind a preallocated ring (same log, same failure
guarantees), the SCHED_FIFO / mlockall set-up that says when it is not permitted, and the bench's exit code."""
from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from hil_sim.direct import DirectDriveGroup
from js2io import cia402
from js2io.logring import RingLog
from js2io.session import Session, open_log
from js2io.trials import TrialContext, load_trials_config, make_trials
from js2spec.log import LogWriter, read_log
from js2spec.robot import load_robot

ROOT = Path(__file__).resolve().parents[1]
ROBOT = load_robot("js2")


def _cfg():
    c = load_trials_config(ROBOT.trials_path)
    c["excitation"].update(period_s=1.0, periods=1, harmonics=2, fade_s=0.2)
    return c


def _session(path, threaded, faults=(), writer=None):
    g = DirectDriveGroup(ROBOT, faults=list(faults))
    g.open()
    w = writer(g) if writer else open_log(path, ROBOT, g)
    trials = make_trials(["excitation"], TrialContext(ROBOT.drives, 1 / 500, _cfg()))
    return Session(g, w, trials, threaded_log=threaded, joint_state=True), g


def test_threaded_log_writes_the_same_log(tmp_path):
    logs = []
    for threaded in (False, True):
        s, _ = _session(tmp_path / f"{threaded}.mcap", threaded, faults=["lost_frames:2@300x4"])
        res = s.run()
        assert not res.aborted, res.text()
        assert isinstance(s.w.writer, RingLog) == threaded
        logs.append(read_log(tmp_path / f"{threaded}.mcap"))
    a, b = logs
    assert len(a.feedback.t) > 900
    for name in ("cycle", "t", "motor_position", "torque", "motor_current", "status", "valid"):
        np.testing.assert_array_equal(getattr(a.feedback, name), getattr(b.feedback, name), err_msg=name)
    for name in ("cycle", "t", "mode", "target_torque"):
        np.testing.assert_array_equal(getattr(a.command, name), getattr(b.command, name), err_msg=name)
    assert a.events == b.events


from test_acq_faults import FullDisk  # noqa: E402 - the same out-of-space file object as the unthreaded test


def test_threaded_log_full_disk_still_stops_and_disables(tmp_path):
    """The disk fills while the writer thread writes: the session sees the flag, aborts, stops every drive, reports
    the log failure in one line, and the part written is readable -- as with the synchronous writer. The direct group
    runs faster than real time, so the thread may meet the error only after the last cycle (clean-clone CI saw
    that): the run is reported aborted all the same (js2-acquire exits 1), the recording being incomplete."""
    path = tmp_path / "full.mcap"

    def writer(g):
        return LogWriter(path, robot=ROBOT.name, cycle_hz=500, source="test", urdf_text=ROBOT.urdf_text,
                         drives_yaml=ROBOT.drives.to_yaml(), opener=lambda p, m: FullDisk(open(p, m), 120_000))
    s, g = _session(path, True, writer=writer)
    res = s.run()
    assert res.aborted and res.reason.startswith("log write failed"), res.text()
    assert "No space left on device" in res.reason and "\n" not in res.reason
    assert all(c.state == cia402.SWITCH_ON_DISABLED for c in g.sim.cores)
    assert "LOG INCOMPLETE" in res.text()
    assert not s.w.writer._thread.is_alive()
    assert len(read_log(path).feedback.t) > 50


class SlowWriter:
    """Records what it is given; each call takes a while (a slow disk)."""

    def __init__(self, n):
        self.n, self.path, self.rows, self.closed = n, "slow", [], False

    def feedback(self, cycle, t, pos, tau, **kw):
        time.sleep(0.002)
        self.rows.append(("fb", cycle, pos.copy()))

    def command(self, cycle, t, mode, tau, target_velocity=None):
        self.rows.append(("cmd", cycle, tau.copy()))

    def event(self, t, kind, trial, **kw):
        self.rows.append(("ev", kind))

    def close(self):
        self.closed = True


def test_ring_full_waits_and_keeps_every_sample_in_order():
    w = SlowWriter(2)
    ring = RingLog(w, capacity=4, poll_s=0.001)
    for k in range(30):
        ring.feedback(k, k * 0.002, np.array([k, -k], dtype=float), np.zeros(2))
        ring.command(k, k * 0.002, np.array([10, 10]), np.array([0.5 * k, 0.0]))
        if k == 10:
            ring.event(0.02, "fault", "x", detail="d")
    ring.close()
    assert w.closed and ring.stalls > 0 and ring.error is None
    kinds = [r[0] for r in w.rows]
    assert len(kinds) == 61 and kinds[22] == "ev" and kinds.count("fb") == 30
    fb = [r for r in w.rows if r[0] == "fb"]
    assert [r[1] for r in fb] == list(range(30)) and all(r[2][1] == -r[1] for r in fb)


def test_rt_setup_off_and_bad_priority():
    from js2io.rt import realtime_setup
    from js2spec.errors import Js2Error
    assert "normal scheduling" in realtime_setup(0)
    with pytest.raises(Js2Error, match="SCHED_FIFO priorities are"):
        realtime_setup(1000)


@pytest.mark.skipif(not hasattr(os, "geteuid") or os.geteuid() != 0, reason="SCHED_FIFO needs root here")
def test_rt_setup_says_it_is_permitted_as_root():
    code = "from js2io.rt import realtime_setup; print(realtime_setup(5))"
    ok = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True).stdout.strip()
    assert ok == "SCHED_FIFO priority 5, memory locked (permitted: running as root)", ok


def test_rt_setup_says_when_not_permitted(monkeypatch):
    """What an unprivileged user sees (the kernel's refusal simulated): one line naming the cause and the remedies."""
    from js2io import rt
    from js2spec.errors import Js2Error

    def refuse(*a):
        raise PermissionError(1, "Operation not permitted")
    monkeypatch.setattr(rt.os, "sched_setscheduler", refuse)
    with pytest.raises(Js2Error) as e:
        rt.realtime_setup(5)
    msg = str(e.value)
    assert msg.startswith("--rt-priority 5: SCHED_FIFO not permitted") and "CAP_SYS_NICE" in msg and "\n" not in msg


def test_bench_exits_nonzero_when_a_run_aborted():
    """An injected drive fault aborts the measurement: the bench says ABORTED and exits 1 (not timed)."""
    out = subprocess.run([sys.executable, "scripts/bench_acquire.py", "--seconds", "2", "--rate", "200",
                          "--transport", "virtual", "--fault", "drive_fault:2@150"],
                         cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert out.returncode == 1, out.stdout + out.stderr
    assert "ABORTED: EMCY node 3" in out.stdout and "missed" in out.stdout and "stale" in out.stdout
    assert "p99" in out.stdout and "run(s) ABORTED" in out.stderr


def test_periodic_sync_runs_a_trial():
    """SYNC from python-can's periodic send (a thread on the virtual bus; the kernel's broadcast manager on
    SocketCAN): the loop follows it, t is the SYNC schedule, the drives saw at least one SYNC per logged cycle."""
    import tempfile

    from hil_sim.canopen_inprocess import InProcessCanopen
    from js2io.session import run_trials
    c = load_trials_config(ROBOT.trials_path)
    c["excitation"].update(period_s=1.0, periods=1, harmonics=2, fade_s=0.2, speed_fraction=0.2)
    with tempfile.TemporaryDirectory() as d, InProcessCanopen(ROBOT, cycle_hz=100, realtime=True,
                                                              sim_realtime=False) as rig:
        rig.group.sync_mode = "periodic"
        res = run_trials(rig.group, ROBOT, ["excitation"], Path(d) / "p.mcap", trials_config=c,
                         max_consecutive_lost=50)
        assert rig.group._sync_task is not None and rig.group.sync_mode == "periodic"
        syncs = rig.sim.syncs
        log = read_log(Path(d) / "p.mcap")
    assert not res.aborted, res.text()
    t = log.feedback.t
    assert len(t) > 150
    k = np.round(t * 100).astype(int)      # on the 100 Hz schedule, strictly increasing
    np.testing.assert_allclose(t, k / 100, atol=1e-9)
    assert np.all(np.diff(k) >= 1)
    assert syncs >= k[-1] - k[0]


def test_auto_sync_is_master_off_socketcan():
    from hil_sim.canopen_inprocess import InProcessCanopen
    with InProcessCanopen(ROBOT, cycle_hz=100, realtime=True) as rig:
        assert rig.group.sync_mode == "auto" and not rig.group._periodic() and rig.group.sync_mode == "master"


@pytest.mark.skipif(not hasattr(os, "geteuid") or os.geteuid() != 0, reason="SCHED_FIFO needs root here")
def test_bench_load_never_inherits_real_time_scheduling():
    """--load beside --rt-priority: the busy loops run at normal priority on any CPU (real-time busy loops would
    take both cores from everything)."""
    code = ("import os, sys; sys.path.insert(0, 'scripts'); import bench_acquire as b\n"
            "os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(5)); os.sched_setaffinity(0, {0})\n"
            "p = b.start_load(1)\n"
            "print(os.sched_getscheduler(p[0].pid) == os.SCHED_OTHER, sorted(os.sched_getaffinity(p[0].pid)))\n"
            "b.stop_load(p)\n")
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert out.stdout.strip() == f"True {list(range(os.cpu_count()))}", out.stdout + out.stderr


def test_bench_bus_limit_from_the_eds_layout():
    """The README's bus limit: SYNC + 6 x RPDO1 (4 B) + 6 x TPDO1 (8 B) at 1 Mbit/s, worst-case stuffing."""
    sys.path.insert(0, str(ROOT / "scripts"))
    import bench_acquire as b
    lim, bits, sizes = b.bus_limit_hz(ROBOT)
    assert sizes == (4, 8) and bits == 1435 and round(lim) == 697 and round(0.9 * lim) == 627
    assert round(b.bus_limit_hz(ROBOT, worst=False)[0]) == 842
