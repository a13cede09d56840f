"""The default trials (configs/js2/trials.yaml, `--trial all`) excite what identification needs: run them once on
the simulator through DirectDriveGroup (same trial code and drive behaviour as the CANopen path, no CAN) and check
the sequential tests' raw material against the simulator's true parameters."""
from __future__ import annotations

import numpy as np
import pytest
import yaml

from hil_sim.direct import DirectDriveGroup
from js2io.session import run_trials
from js2spec.log import read_log
from js2spec.robot import load_robot

ROBOT = load_robot("js2")
TRUTH = yaml.safe_load(ROBOT.sim_truth_path.read_text())


@pytest.fixture(scope="module")
def full(tmp_path_factory):
    path = tmp_path_factory.mktemp("all") / "all.mcap"
    res = run_trials(DirectDriveGroup(ROBOT, seed=3), ROBOT, ["static", "velocity", "acceleration", "excitation",
                                                             "validation"], path)
    assert not res.aborted, res.text()
    return res, read_log(path)


def test_total_duration_reasonable(full):
    res, log = full
    assert 120.0 <= log.feedback.t[-1] <= 240.0, log.feedback.t[-1]
    assert log.trials() == ["static", "velocity", "acceleration", "excitation", "validation"]
    assert np.all(np.abs(log.command.target_torque) <= np.asarray(ROBOT.drives.torque_limit) + 1e-12)


def test_static_breakaways_give_fs_within_2_percent(full):
    _, log = full
    fs_true = np.asarray(TRUTH["static"])
    br = {}
    for e in log.events:
        if e["kind"] == "breakaway":
            br.setdefault((tuple(e["pose"]), e["joint"]), {})[e["direction"]] = e["value"]
    assert len(br) == 2 * 6
    for (pose, j), v in br.items():
        fs = (v[1] - v[-1]) / 2
        assert abs(fs / fs_true[j] - 1) < 0.02, (pose, j, fs, fs_true[j])


def test_velocity_segments_steady_at_several_speeds(full):
    _, log = full
    fb = log.feedback
    speeds = {}
    for ev, t_end in log.segments("velocity"):
        j, d, v = ev["joint"], ev["direction"], ev["speed"]
        k0, k1 = np.searchsorted(fb.t, [ev["t"], t_end])
        assert (k1 - k0) * 0.002 >= 0.25, "steady segment too short"
        vel = np.diff(fb.motor_position[k0:k1, j]) / np.diff(fb.t[k0:k1])
        assert abs(vel.mean() - d * v) < 0.02 * v + 0.5, (j, d, v, vel.mean())
        speeds.setdefault(j, set()).add((d, round(v, 3)))
    assert sorted(speeds) == list(range(6))
    for j, s in speeds.items():
        assert len({v for _, v in s}) >= 4 and {d for d, _ in s} == {1, -1}
        vmax = max(v for _, v in s)
        assert vmax >= 0.6 * ROBOT.drives.velocity_limit[j], (j, vmax)


def test_acceleration_moves_all_axes_within_limits(full):
    _, log = full
    fb = log.feedback
    segs = log.segments("acceleration")
    assert len(segs) >= 10
    moved = np.zeros(6)
    for ev, t_end in segs:
        k0, k1 = np.searchsorted(fb.t, [ev["t"], t_end])
        moved = np.maximum(moved, np.ptp(fb.motor_position[k0:k1], axis=0))
    K = np.asarray(ROBOT.drives.gear_ratio_matrix)
    assert np.all(np.abs(K) @ moved > 0.5), moved       # every joint swept at least 0.5 rad somewhere
    q = fb.motor_position @ K.T
    assert np.all(q >= ROBOT.drives.position_min) and np.all(q <= ROBOT.drives.position_max)
    v = np.diff(fb.motor_position, axis=0) / 0.002
    assert np.all(np.abs(v).max(axis=0) <= 1.1 * np.asarray(ROBOT.drives.velocity_limit))


def test_excitation_and_validation_differ_and_stay_inside(full):
    _, log = full
    fb = log.feedback
    K = np.asarray(ROBOT.drives.gear_ratio_matrix)
    paths = []
    for trial in ("excitation", "validation"):
        (ev, t_end), = log.segments(trial)
        k0, k1 = np.searchsorted(fb.t, [ev["t"], t_end])
        q = fb.motor_position[k0:k1] @ K.T
        assert np.all(np.ptp(q, axis=0) > 0.3), (trial, np.ptp(q, axis=0))
        paths.append(q[:1000])
    assert not np.allclose(paths[0], paths[1], atol=0.05)
