"""CSV (mode 9): the velocity trial run by the drives' own velocity loop. Exercises the mode change by SDO
(0x6060/0x6061), RPDO2 (0x60FF) and the simulated drive's loop; CAN path and direct path give the same log."""
from __future__ import annotations

import numpy as np

from hil_sim.canopen_inprocess import InProcessCanopen
from hil_sim.direct import DirectDriveGroup
from js2io.session import run_trials
from js2io.trials import load_trials_config
from js2spec.log import read_log
from js2spec.robot import load_robot

ROBOT = load_robot("js2")


def _cfg():
    c = load_trials_config(ROBOT.trials_path)
    c["velocity"].update(mode="csv", axes=[1, 3], speed_fractions=[0.2, 1.0], steady_s=0.4)
    return c


def test_csv_velocity_trial_over_canopen_matches_direct(tmp_path):
    with InProcessCanopen(ROBOT) as rig:
        res = run_trials(rig.group, ROBOT, ["velocity"], tmp_path / "can.mcap", trials_config=_cfg())
    assert not res.aborted, res.text()
    res_d = run_trials(DirectDriveGroup(ROBOT), ROBOT, ["velocity"], tmp_path / "dir.mcap", trials_config=_cfg())
    assert not res_d.aborted
    can, direct = read_log(tmp_path / "can.mcap"), read_log(tmp_path / "dir.mcap")
    assert np.array_equal(can.feedback.motor_position, direct.feedback.motor_position)
    assert np.array_equal(can.command.target_velocity, direct.command.target_velocity, equal_nan=True)
    modes = can.command.mode
    assert (modes[:, 1] == 9).any() and (modes[:, 3] == 9).any() and not (modes[:, [0, 2, 4, 5]] == 9).any()
    assert np.all(can.command.target_torque[modes == 9] == 0.0)   # in CSV the torque is the drive's
    fb = can.feedback
    segs = can.segments("velocity")
    assert len(segs) == 8
    for ev, t_end in segs:
        k0, k1 = np.searchsorted(fb.t, [ev["t"], t_end])
        v = np.diff(fb.motor_position[k0:k1, ev["joint"]]) / 0.002
        assert abs(v.mean() - ev["direction"] * ev["speed"]) < 0.02 * ev["speed"], (ev, v.mean())
        assert np.all(modes[k0:k1, ev["joint"]] == 9)


def test_real_time_master_and_wall_clock_physics(tmp_path):
    """--realtime: SYNC paced by the wall clock, the simulator's physics on its own wall-clock thread (100 Hz here,
    gentle on a shared machine; speed is measured by scripts/bench_acquire.py, not asserted)."""
    c = load_trials_config(ROBOT.trials_path)
    c["excitation"].update(period_s=2.0, periods=1, harmonics=3, fade_s=0.3, speed_fraction=0.2)
    with InProcessCanopen(ROBOT, cycle_hz=100, realtime=True) as rig:
        res = run_trials(rig.group, ROBOT, ["excitation"], tmp_path / "rt.mcap", trials_config=c,
                         max_consecutive_lost=50)
        plant_t = rig.sim.plant.t
    assert not res.aborted, res.text()
    log = read_log(tmp_path / "rt.mcap")
    t = log.feedback.t
    assert len(t) > 300 and np.all(np.diff(t) > 0)
    assert not np.allclose(t, log.feedback.cycle / 100.0, atol=1e-9, rtol=0), "t must be the measured SYNC time"
    assert plant_t >= 0.8 * t[-1]     # the physics advanced with the wall clock, not per SYNC
    assert log.meta["cycle_hz"] == "100"
