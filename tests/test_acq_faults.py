"""Safety: every fault the simulated drives can inject stops the trial safely.

Real CANopen frames on python-can's virtual bus (master and six simulated drives in this process). Each test checks:
the drives end disabled (asked of the simulated drives themselves, not of the log), no command above the torque limit
(every logged command), and the log is readable with the fault recorded.
"""
from __future__ import annotations

import numpy as np
import pytest
import yaml

from hil_sim.canopen_inprocess import InProcessCanopen
from hil_sim.direct import DirectDriveGroup
from js2io import cia402
from js2io.group import Command
from js2io.session import run_trials
from js2io.trials import Trial, load_trials_config
from js2spec.log import read_log
from js2spec.robot import load_robot

ROBOT = load_robot("js2")


@pytest.fixture(scope="module")
def cfg(tmp_path_factory):
    c = load_trials_config(ROBOT.trials_path)
    c["excitation"].update(period_s=2.0, periods=2, harmonics=3, fade_s=0.3)
    p = tmp_path_factory.mktemp("cfg") / "trials.yaml"
    c.pop("_path")
    p.write_text(yaml.safe_dump(c))
    return load_trials_config(p)


def _check_log(path, *, kinds=("fault", "abort"), detail_has=None):
    log = read_log(path)
    lim = np.asarray(ROBOT.drives.torque_limit)
    assert log.command is not None and len(log.command.t) > 10
    over = np.abs(log.command.target_torque) > lim[None, :] + 1e-12
    assert not over.any(), f"commanded torque above the limit in {over.any(axis=1).sum()} cycles"
    ev = log.events
    got = {e["kind"] for e in ev}
    for k in kinds:
        assert k in got, f"no {k!r} event; events: {[(e['kind'], e.get('detail')) for e in ev[-6:]]}"
    if detail_has:
        text = " ".join(e.get("detail", "") for e in ev if e["kind"] in ("fault", "abort"))
        assert detail_has in text, text
    return log


def _assert_disabled(sim_set, skip=()):
    for i, c in enumerate(sim_set.cores):
        if i in skip:
            continue
        assert c.state in (cia402.SWITCH_ON_DISABLED, cia402.FAULT, cia402.READY), f"drive {i} ends in {c.state}"


def _run_can(tmp_path, cfg, faults=(), hook=None, trials=("excitation",), max_lost=10):
    path = tmp_path / "f.mcap"
    with InProcessCanopen(ROBOT, faults=list(faults)) as rig:
        res = run_trials(rig.group, ROBOT, list(trials), path, trials_config=cfg, session_hook=hook,
                         max_consecutive_lost=max_lost)
        states = [c.state for c in rig.sim.set.cores]
        sim_set = rig.sim.set
    return res, path, sim_set, states


@pytest.mark.parametrize("fault,detail", [
    ("drive_fault:2@400", "EMCY node 3"),
    ("dead_node:4@400", "drive 4"),
    ("bus_error@400", "bus error"),
])
def test_fault_stops_trial_safely(tmp_path, cfg, fault, detail):
    res, path, sim_set, states = _run_can(tmp_path, cfg, [fault])
    assert res.aborted, res.text()
    assert detail in res.reason or detail in " ".join(
        e.get("detail", "") for e in read_log(path).events), res.reason
    if fault.startswith("bus_error"):
        # bus-off: the master cannot reach the drives any more; they stop on their own (heartbeat consumer ->
        # quick stop -> disabled at standstill): see test_bus_error_drives_quick_stop_without_master
        pass
    else:
        _assert_disabled(sim_set, skip=(4,) if fault.startswith("dead") else ())
    _check_log(path, detail_has=detail)
    if fault.startswith("drive_fault"):     # the project's specific name, not canopen's generic class
        assert "0x2310 continuous over-current" in res.reason, res.reason


def test_bus_error_drives_quick_stop_without_master(tmp_path, cfg):
    """After a bus-off the master's heartbeat no longer reaches the drives: they quick-stop by themselves."""
    import time
    path = tmp_path / "b.mcap"
    with InProcessCanopen(ROBOT, faults=["bus_error@300"]) as rig:
        res = run_trials(rig.group, ROBOT, ["excitation"], path, trials_config=cfg)
        # the simulated drives' own view: after bus-off nothing more arrives; quick stop after 3 x heartbeat
        rig.group.stop_heartbeat()
        # the drives see no master heartbeat: quick stop, then disabled at standstill (wall clock: the consumer
        # timeout; SYNCs no longer reach them, so step their physics as the wall clock would)
        t_end = time.monotonic() + 5.0
        while time.monotonic() < t_end and any(c.state != cia402.SWITCH_ON_DISABLED for c in rig.sim.set.cores):
            time.sleep(0.05)
            with rig.sim.set.lock:
                rig.sim.set.on_sync()
        states = [c.state for c in rig.sim.set.cores]
    assert res.aborted and "bus error" in res.text()
    assert all(s == cia402.SWITCH_ON_DISABLED for s in states), states
    _check_log(path, detail_has="bus error")


def test_lost_frames_are_marked_and_counted(tmp_path, cfg):
    res, path, sim_set, _ = _run_can(tmp_path, cfg, ["lost_frames:1@300x3", "lost_frames:5@500x2"])
    assert not res.aborted, res.text()
    log = read_log(path)
    invalid = ~log.feedback.valid
    assert invalid[:, 1].sum() == 3 and invalid[:, 5].sum() == 2 and invalid[:, [0, 2, 3, 4]].sum() == 0
    assert res.lost == [0, 3, 0, 0, 0, 2]
    _assert_disabled(sim_set)
    _check_log(path, kinds=("trial_start", "trial_end"))


def test_lost_frames_beyond_limit_abort(tmp_path, cfg):
    res, path, sim_set, _ = _run_can(tmp_path, cfg, ["lost_frames:3@300x40"], max_lost=10)
    assert res.aborted and "consecutive TPDOs lost" in res.reason
    _assert_disabled(sim_set)
    _check_log(path, detail_has="consecutive TPDOs lost")


def test_master_heartbeat_loss_quick_stops_drives(tmp_path, cfg):
    """The master's heartbeat producer stops: the drives' consumer times out -> quick stop + EMCY 0x8130."""
    def hook(session):
        def on_cycle(s, fb):
            if fb.cycle == 300:
                s.g.stop_heartbeat()
        session.on_cycle = on_cycle
    res, path, sim_set, _ = _run_can(tmp_path, cfg, hook=hook)
    assert res.aborted, res.text()
    log = _check_log(path, detail_has="0x8130")
    _assert_disabled(sim_set)


class PushOut(Trial):
    """Test trial: constant torque on drive 3 (j4) until it leaves the joint envelope."""
    name = "push_out"

    def step(self, fb):
        from js2io.trials import TrialStep
        tau = np.zeros(self.ctx.n)
        tau[3] = 0.5   # beyond the 0.09 N*m limit on purpose: the group must clamp it
        return TrialStep(Command(tau, mode=np.full(self.ctx.n, 10)), [], done=False)


def test_leaving_envelope_quick_stops(tmp_path, cfg):
    from js2io.trials import TrialContext
    ctx = TrialContext(ROBOT.drives, 1 / 500, cfg)
    res, path, sim_set, _ = _run_can(tmp_path, cfg, trials=[PushOut(ctx)])
    assert res.aborted and "left the envelope" in res.reason, res.text()
    log = _check_log(path, kinds=("abort",), detail_has="left the envelope")
    assert np.isclose(np.abs(log.command.target_torque[:, 3]).max(), ROBOT.drives.torque_limit[3], atol=1e-4)
    _assert_disabled(sim_set)


def test_direct_group_faults_match(tmp_path, cfg):
    """The CAN-less group reports the same faults (for fast tests elsewhere)."""
    path = tmp_path / "d.mcap"
    g = DirectDriveGroup(ROBOT, faults=["drive_fault:1@400"])
    res = run_trials(g, ROBOT, ["excitation"], path, trials_config=cfg)
    assert res.aborted and "EMCY node 2" in res.reason
    _assert_disabled(g.sim)
    _check_log(path, detail_has="0x2310")


class FullDisk:
    """A real file that runs out of space after `limit` bytes, as a small tmpfs does (OSError ENOSPC)."""

    def __init__(self, f, limit):
        self.f, self.limit, self.written = f, limit, 0

    def write(self, b):
        import errno
        if self.written + len(b) > self.limit:
            raise OSError(errno.ENOSPC, "No space left on device")
        self.written += len(b)
        return self.f.write(b)

    def __getattr__(self, name):
        return getattr(self.f, name)


def test_full_disk_mid_trial_still_stops_and_disables(tmp_path, cfg):
    """The log's disk fills up mid-trial: the session aborts, ramps/quick-stops and disables every drive (asked of
    the simulated drives), then reports the log failure in one line; the part written before is readable."""
    from js2io.session import Session
    from js2io.trials import TrialContext, make_trials
    from js2spec.log import LogWriter
    path = tmp_path / "full.mcap"
    with InProcessCanopen(ROBOT) as rig:
        ctx = TrialContext(ROBOT.drives, 1 / 500, cfg)
        rig.group.open()
        w = LogWriter(path, robot=ROBOT.name, cycle_hz=500, source="test", urdf_text=ROBOT.urdf_text,
                 drives_yaml=ROBOT.drives.to_yaml(), opener=lambda p, m: FullDisk(open(p, m), 120_000))
        res = Session(rig.group, w, make_trials(["excitation"], ctx)).run()
        states = [c.state for c in rig.sim.set.cores]
        sim_set = rig.sim.set
    assert res.aborted and res.reason.startswith("log write failed"), res.text()
    assert "No space left on device" in res.reason and "\n" not in res.reason
    _assert_disabled(sim_set)
    assert res.final_states == [cia402.SWITCH_ON_DISABLED] * 6, res.final_states
    assert "LOG INCOMPLETE" in res.text()
    assert max(res.max_abs_command[i] - ROBOT.drives.torque_limit[i] for i in range(6)) <= 1e-9
    log = read_log(path)          # what reached the disk before it filled: readable, flagged as recovered
    assert len(log.feedback.t) > 50


def test_bus_gone_summary_does_not_claim_disabled(tmp_path, cfg):
    """After a bus-off no drive can answer the stop: the summary says so instead of repeating the last state."""
    res, path, sim_set, _ = _run_can(tmp_path, cfg, ["bus_error@300"])
    assert res.aborted and "\n" not in res.reason
    assert res.final_states == ["NOT CONFIRMED DISABLED (no answer)"] * 6, res.final_states
    assert "OPERATION ENABLED" not in res.text().split("drives at the end:")[1]


def test_progress_bar_only_on_a_terminal(tmp_path, cfg, monkeypatch):
    """stderr redirected to a file (CI, a log): no bar, so no carriage-return updates fill the file."""
    import io
    err = io.StringIO()
    monkeypatch.setattr("sys.stderr", err)
    from js2io.session import Session, open_log
    from js2io.trials import TrialContext, make_trials
    g = DirectDriveGroup(ROBOT)
    g.open()
    w = open_log(tmp_path / "p.mcap", ROBOT, g, cfg)
    res = Session(g, w, make_trials(["excitation"], TrialContext(ROBOT.drives, 1 / 500, cfg)), progress=True).run()
    assert not res.aborted, res.text()
    assert "\r" not in err.getvalue() and "cyc" not in err.getvalue()


class Saturating(Trial):
    """Test trial: asks drive 3 for twice its torque limit, alternating sign at 5 Hz, for 0.4 s (the others
    free: longer and the unheld shoulder sags out of the envelope)."""
    name = "saturating"

    def step(self, fb):
        from js2io.trials import TrialStep
        tau = np.zeros(self.ctx.n)
        tau[3] = 2 * ROBOT.drives.torque_limit[3] * np.sign(np.sin(2 * np.pi * 5 * fb.t) + 1e-9)
        return TrialStep(Command(tau, mode=np.full(self.ctx.n, 10)), [], done=fb.cycle > 200)


def test_saturation_is_warned_and_clamped(tmp_path, cfg):
    from js2io.trials import TrialContext
    ctx = TrialContext(ROBOT.drives, 1 / 500, cfg)
    g = DirectDriveGroup(ROBOT)
    res = run_trials(g, ROBOT, [Saturating(ctx)], tmp_path / "s.mcap", trials_config=cfg)
    assert not res.aborted, res.text()
    assert len(res.warnings) == 1 and "drive 3" in res.warnings[0] and "'saturating'" in res.warnings[0]
    assert "WARNING: drive 3" in res.text()
    assert res.max_abs_command[3] == pytest.approx(ROBOT.drives.torque_limit[3], abs=1e-4)
    log = _check_log(tmp_path / "s.mcap", kinds=("trial_start", "trial_end"))
