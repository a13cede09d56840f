"""Logs for the identification tests.

* :func:`sim_session` — the paper's trials through the real trial code (``js2io.session.run_trials``) on the simulated
  drives without CAN (``hil_sim.direct.DirectDriveGroup``): one trial implementation for acquisition and tests.
  Generated once per test run (``shared_data``: one folder, shared by pytest-xdist's workers).
* :func:`synthetic_log` — a small log written straight through ``LogWriter`` from eq. 1 with known parameters
  (regressor x parameters + noise): no simulator, for the error-path and end-to-end tests that need a log quickly.
"""
from __future__ import annotations

import functools
from pathlib import Path

import numpy as np

from js2spec.log import LogWriter
from shared_data import build_once, folder, key


REPO = Path(__file__).resolve().parents[1]
REAL = REPO.parent / "shared" / "data" / "real"


def prove_diagnosis_real():
    """scripts/prove_diagnosis_real.py as a module, one instance per test session (the modules that diagnose the
    real recordings share its helpers)."""
    import importlib.util
    import sys

    mod = sys.modules.get("prove_diagnosis_real")
    if mod is None:
        spec = importlib.util.spec_from_file_location("prove_diagnosis_real",
                                                      REPO / "scripts" / "prove_diagnosis_real.py")
        mod = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(mod)
        sys.modules["prove_diagnosis_real"] = mod
    return mod


@functools.lru_cache(maxsize=None)
def sim_session(trials: tuple = ("static", "velocity", "acceleration", "validation"), seed: int = 0,
                effects: tuple = ()) -> Path:
    """A simulator session log (true parameters: configs/js2/sim_truth.yaml) with the requested trials."""
    from hil_sim.direct import DirectDriveGroup
    from hil_sim.plant import Plant
    from js2io.session import run_trials
    from js2spec.robot import load_robot

    path = folder("id_tests") / f"sim_{'_'.join(trials)}_{seed}_{key(trials, seed, effects)}.mcap"
    with build_once(path) as build:
        if build:
            robot = load_robot("js2")
            plant = Plant(robot, seed=seed, effects=[{k: (list(v) if isinstance(v, tuple) else v)
                                                      for k, v in dict(e).items()} for e in effects]) if effects else None
            with DirectDriveGroup(robot, plant=plant, seed=seed) as group:
                res = run_trials(group, robot, list(trials), path)
            assert not res.aborted, res.reason
    return path


def truth_vector(arm):
    """The simulator's true standard parameter vector (URDF inertials + sim_truth drive terms) for ``arm``."""
    from hil_sim.truth import load_truth
    from identification.regressor import standard_vector
    from js2spec.robot import load_robot

    tr = load_truth(load_robot("js2"))
    return tr, standard_vector(arm, motor_inertia=tr.motor_inertia, viscous=tr.viscous, coulomb=tr.coulomb)


def synthetic_log(path: Path, *, seconds: float = 12.0, trial: str = "acceleration", seed: int = 0,
                  noise: float = 2e-4, nan_joint: int | None = None, nan_rows: int = 0, version: str | None = None,
                  urdf_text: str | None = None, gap: tuple | None = None, validation: bool = True,
                  params=None) -> Path:
    """A Js-2 log whose torques are eq. 1 evaluated exactly (known parameters) on a multi-sine motion, plus noise.
    Options inject the faults the tests need (NaNs, wrong version, another URDF, a counter gap)."""
    from identification.regressor import arm_model, build_regressor, standard_vector
    from js2spec.robot import load_robot

    robot = load_robot("js2")
    drives = robot.drives
    arm = arm_model(robot.urdf_text, drives)
    rng = np.random.default_rng(seed)
    fs = 500.0
    t = np.arange(int(seconds * fs)) / fs
    n = drives.n
    qj = np.zeros((len(t), n))
    for j in range(n):
        for f in (0.2, 0.45, 0.9, 1.6):
            qj[:, j] += 0.25 * rng.uniform(0.3, 1.0) * np.sin(2 * np.pi * f * t + rng.uniform(0, 2 * np.pi)) / (1 + f)
    Kinv = np.linalg.inv(drives.gear_ratio_matrix)
    qm = (qj - drives.joint_offset) @ Kinv.T
    dqm = np.gradient(qm, 1 / fs, axis=0)
    ddqm = np.gradient(dqm, 1 / fs, axis=0)
    if params is None:
        params = standard_vector(arm, motor_inertia=[3e-5, 3e-5, 1.6e-5, 8e-6, 6e-6, 6e-6],
                                 viscous=[2e-4, 2.2e-4, 1.5e-4, 8e-5, 6e-5, 6e-5],
                                 coulomb=[0.02, 0.024, 0.012, 0.008, 0.006, 0.006])
    tau = build_regressor(arm, qm, dqm, ddqm) @ params + noise * rng.normal(size=qm.shape)
    kt = np.asarray(drives.torque_constant)
    if nan_joint is not None:
        rows = slice(None) if nan_rows == 0 else slice(100, 100 + nan_rows)
        tau[rows, nan_joint] = np.nan
    extra = {"version": version} if version is not None else None
    keep = np.ones(len(t), dtype=bool)
    if gap is not None:
        keep[gap[0]:gap[1]] = False
    split = int(len(t) * 0.75) if validation else len(t)
    with LogWriter(path, robot="js2", cycle_hz=fs, source="hil_sim:synthetic eq. 1", urdf_text=urdf_text or
                   robot.urdf_text, drives_yaml=robot.drives_yaml, extra_metadata=extra) as w:
        w.event(0.0, "trial_start", trial)
        w.event(0.0, "segment_start", trial)
        for k in range(len(t)):
            if k == split and validation:
                w.event(t[k], "segment_end", trial)
                w.event(t[k], "trial_end", trial)
                w.event(t[k], "trial_start", "validation")
                w.event(t[k], "segment_start", "validation")
            if keep[k]:
                w.feedback(k, t[k], qm[k], tau[k], motor_current=tau[k] / kt)
        name = "validation" if validation else trial
        w.event(t[-1], "segment_end", name)
        w.event(t[-1], "trial_end", name)
    return path
