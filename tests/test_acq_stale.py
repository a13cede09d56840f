"""Stale feedback: a burst of TPDOs that do not come back never makes the master push a joint out of its envelope,
and the master's envelope check trips before the drive's own software position limit (0x607D, EMCY 0x8612).

Not timed: the CAN-less simulated drives (`hil_sim.direct`) step one period per SYNC and drop the TPDOs of one drive
(`lost_frames` fault) exactly when the joint is about to reach the envelope, under a trial that pushes it out.
"""
from __future__ import annotations

import numpy as np
import pytest

from hil_sim.direct import DirectDriveGroup
from js2io.group import Command
from js2io.session import run_trials
from js2io.trials import Trial, TrialContext, TrialStep, load_trials_config
from js2spec.log import read_log
from js2spec.robot import load_robot

ROBOT = load_robot("js2")
CFG = load_trials_config(ROBOT.trials_path)
DRIVE = 3          # j4: a light joint, fast towards its envelope at the torque limit


class PushOut(Trial):
    """Constant torque (beyond the limit: the group clamps it) on one drive, towards +q, for ever."""
    name = "push_out"

    def step(self, fb):
        tau = np.zeros(self.ctx.n)
        tau[DRIVE] = 0.5
        return TrialStep(Command(tau, mode=np.full(self.ctx.n, 10)), [], done=False)


def _run(tmp_path, faults=(), max_lost=10 ** 6, name="s.mcap"):
    """Returns the result, the log and the true encoder counts of DRIVE every cycle (what the drive itself sees)."""
    g = DirectDriveGroup(ROBOT, faults=list(faults))
    true_counts = []

    def hook(session):
        session.on_cycle = lambda s, fb: true_counts.append(int(g.sim.last_sensors.encoder_counts[DRIVE]))
    res = run_trials(g, ROBOT, [PushOut(TrialContext(ROBOT.drives, 1 / 500, CFG))], tmp_path / name,
                     trials_config=CFG, max_consecutive_lost=max_lost, session_hook=hook)
    return res, read_log(tmp_path / name), np.asarray(true_counts), g


@pytest.fixture(scope="module")
def fresh_abort_cycle(tmp_path_factory):
    res, log, _, _ = _run(tmp_path_factory.mktemp("fresh"))
    assert res.aborted and "left the envelope" in res.reason, res.text()
    bad = [e for e in log.events if e["kind"] == "abort"]
    return int(round(bad[0]["t"] * 500))


@pytest.mark.parametrize("lead", [3, 15, 40])
def test_stale_burst_master_trips_first_and_never_pushes_on(tmp_path, fresh_abort_cycle, lead):
    """The TPDOs of the moving drive stop `lead` cycles before the joint would reach the envelope, for good, and the
    consecutive-loss limit is out of the way: only the stale-feedback rules protect the arm."""
    start = fresh_abort_cycle - lead
    res, log, true_counts, g = _run(tmp_path, [f"lost_frames:{DRIVE}@{start}x100000"])
    # the master tripped, on its envelope check (with the stale joint's estimate), not the drive
    assert res.aborted and "left the envelope" in res.reason, res.text()
    assert "predicted" in res.reason, res.reason
    codes = [int(e.get("value", 0)) for e in log.events if e["kind"] == "fault"]
    assert 0x8612 not in codes, [(e["kind"], e.get("detail")) for e in log.events]
    core = g.sim.cores[DRIVE]
    assert core.error_code != 0x8612
    # at the master's decision the motor itself was still inside the drive's limits (the quick stop that follows
    # brakes at the drive's torque limit; the drive checks 0x607D only while it follows the master's targets)
    k_abort = int(round([e["t"] for e in log.events if e["kind"] == "abort"][0] * 500))
    seen = true_counts[:k_abort + 1]
    assert (seen >= core.pos_min).all() and (seen <= core.pos_max).all(), (seen.max(), core.pos_max)
    # every command during the burst: the last one held for at most 2 cycles, then zero torque
    valid = log.feedback.valid
    cyc_fb = {int(c): k for k, c in enumerate(log.feedback.cycle)}
    trial_t = [e["t"] for e in log.events if e["kind"] == "trial_start"][0]
    abort_t = [e["t"] for e in log.events if e["kind"] == "abort"][0]
    run, last_fresh_cmd, n_zero, n_held = 0, None, 0, 0
    for k, c in enumerate(log.command.cycle):
        t = log.command.t[k]
        if not trial_t <= t < abort_t:
            continue
        tau = log.command.target_torque[k]
        if valid[cyc_fb[int(c)]].all():
            run, last_fresh_cmd = 0, tau
            continue
        run += 1
        if run <= 2 and np.array_equal(tau, last_fresh_cmd):
            n_held += 1          # held (only while clear of the envelope: near it, zero at once)
        else:
            assert not tau.any(), (c, tau)
            n_zero += 1
    assert res.stale[DRIVE] > 0 and sum(res.stale) == res.stale[DRIVE], res.stale
    assert n_zero > 0 and res.stale_held == n_held <= 2 and res.stale_zeroed == n_zero
    assert "stale cycles per drive" in res.text()


def test_without_the_stale_rules_the_drive_limit_would_trip(tmp_path, fresh_abort_cycle):
    """The scenario is a real hazard: a master that keeps pushing on stale feedback (hold for ever, no estimate)
    runs the joint into the drive's software limit -- the arm stops only by the drive's fault."""
    from js2io import session as sess

    class Naive(sess.Session):
        def motor_position_estimate(self, fb):
            return fb.motor_position

        def _stale_command(self):
            return self.g.sent
    start = fresh_abort_cycle - 15
    g = DirectDriveGroup(ROBOT, faults=[f"lost_frames:{DRIVE}@{start}x100000"])
    g.open()
    w = sess.open_log(tmp_path / "n.mcap", ROBOT, g)
    res = Naive(g, w, [PushOut(TrialContext(ROBOT.drives, 1 / 500, CFG))], max_consecutive_lost=10 ** 6).run()
    assert res.aborted and "0x8612" in res.reason, res.text()


def test_stale_counts_in_summary_and_metadata(tmp_path):
    """Short bursts on two drives during a normal trial: counted per drive, trial completes."""
    cfg = load_trials_config(ROBOT.trials_path)
    cfg["excitation"].update(period_s=1.0, periods=1, harmonics=2, fade_s=0.2)
    g = DirectDriveGroup(ROBOT, faults=["lost_frames:1@300x3", "lost_frames:5@500x5"])
    res = run_trials(g, ROBOT, ["excitation"], tmp_path / "c.mcap", trials_config=cfg)
    assert not res.aborted, res.text()
    assert res.stale == [0, 3, 0, 0, 0, 5] and res.longest_stale == [0, 3, 0, 0, 0, 5]
    assert res.stale_held == 4 and res.stale_zeroed == 4    # 2 held per burst, then zero: 1 + 3
    log = read_log(tmp_path / "c.mcap")
    from mcap.reader import make_reader
    with open(tmp_path / "c.mcap", "rb") as f:
        meta = {m.name: m.metadata for m in make_reader(f).iter_metadata()}["js2_acquire_summary"]
    assert meta["stale_cycles_per_drive"] == "0,3,0,0,0,5"
    assert sum("stale feedback" in e.get("detail", "") for e in log.events) == 2    # one per burst beyond the hold
