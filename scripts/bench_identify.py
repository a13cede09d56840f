#!/usr/bin/env python3
"""Benchmark of js2-identify: wall time and peak memory for a 60 s, 500 Hz, 6-axis session, the regressor's
samples/s against bare pinocchio (ratio, same run), and how time grows with 1x / 4x / 16x the samples.

    .venv/bin/python scripts/bench_identify.py [--quick]

1. A 60 s session from the simulator through the real trial code (js2io trials on hil_sim.direct.DirectDriveGroup:
   static, velocity, acceleration, validation, shortened to 60 s in total), identified with the mixed method. Reading
   the log (js2spec.log.read_log) and identifying are timed separately; peak memory by tracemalloc (Python + numpy
   allocations) and the process's max RSS.
2. The regressor: identification.regressor.build_regressor (eq. 1 motor side: K^T Y, motor columns) vs a bare loop of
   pinocchio.computeJointTorqueRegressor on the same states.
3. Growth: synthetic eq. 1 sessions (acceleration + validation trials, simultaneous method) of 60 s, 240 s and 960 s;
   identification time per sample should stay flat (linear growth). RLS runs 35,000 iterations at most (the paper's
   setting), batch OLS/WLS and the regressor use every sample.
Goal: the whole 60 s session in under 2 s, linear growth. (Timing only here: tests never assert speed.)
"""
from __future__ import annotations

import os

# Single-threaded BLAS: the matrices here are small (~50 parameters) and OpenBLAS's spinning worker threads make a
# loaded 2-core machine several times slower. Set before numpy is first imported; a user's own setting wins.
for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")
import argparse
import resource
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))


def session_60s(path: Path) -> Path:
    from hil_sim.direct import DirectDriveGroup
    from js2io.session import run_trials
    from js2io.trials import load_trials_config
    from js2spec.robot import load_robot

    robot = load_robot("js2")
    cfg = load_trials_config(robot.trials_path)
    cfg["static"]["poses"] = cfg["static"]["poses"][:1]
    cfg["static"]["settle_s"] = 0.2
    cfg["static"]["backoff_s"] = 0.15
    cfg["velocity"]["speed_fractions"] = [0.3, 1.0]
    cfg["velocity"]["steady_s"] = 0.2
    cfg["velocity"]["settle_s"] = 0.08
    cfg["acceleration"]["durations"] = [1.3, 1.0]
    cfg["acceleration"]["strokes_per_duration"] = 4
    cfg["validation"]["periods"] = 1.0
    cfg["validation"]["period_s"] = 3.0
    with DirectDriveGroup(robot, seed=0) as group:
        run_trials(group, robot, ["static", "velocity", "acceleration", "validation"], path, trials_config=cfg)
    return path


def synthetic_session(path: Path, seconds: float, seed: int = 0) -> Path:
    """Eq. 1 evaluated exactly (URDF inertials, plausible drive terms) on a multi-sine motion, plus noise."""
    from identification.regressor import arm_model, build_regressor, standard_vector
    from js2spec.log import LogWriter
    from js2spec.robot import load_robot

    robot = load_robot("js2")
    d = robot.drives
    arm = arm_model(robot.urdf_text, d)
    rng = np.random.default_rng(seed)
    fs = 500.0
    t = np.arange(int(seconds * fs)) / fs
    qj = np.zeros((len(t), d.n))
    for j in range(d.n):
        for f in (0.2, 0.45, 0.9, 1.6):
            qj[:, j] += 0.25 * rng.uniform(0.3, 1) * np.sin(2 * np.pi * f * t + rng.uniform(0, 6.3)) / (1 + f)
    Kinv = np.linalg.inv(d.gear_ratio_matrix)
    qm = qj @ Kinv.T
    dqm = np.gradient(qm, 1 / fs, axis=0)
    ddqm = np.gradient(dqm, 1 / fs, axis=0)
    pi = standard_vector(arm, motor_inertia=[3e-5, 3e-5, 1.6e-5, 8e-6, 6e-6, 6e-6],
                         viscous=[2e-4, 2.2e-4, 1.5e-4, 8e-5, 6e-5, 6e-5], coulomb=[0.02, 0.024, 0.012, 0.008, 0.006, 0.006])
    tau = build_regressor(arm, qm, dqm, ddqm) @ pi + 2e-4 * rng.normal(size=qm.shape)
    kt = np.asarray(d.torque_constant)
    split = int(0.8 * len(t))
    with LogWriter(path, robot="js2", cycle_hz=fs, source="hil_sim:bench synthetic eq. 1", urdf_text=robot.urdf_text,
                   drives_yaml=robot.drives_yaml) as w:
        w.event(0.0, "trial_start", "acceleration")
        for k in range(len(t)):
            if k == split:
                w.event(t[k], "trial_end", "acceleration")
                w.event(t[k], "trial_start", "validation")
            w.feedback(k, t[k], qm[k], tau[k], motor_current=tau[k] / kt)
        w.event(t[-1], "trial_end", "validation")
    return path


def timed_identify(path: Path, method: str):
    from identification.pipeline import IdentifyOptions, identify
    from js2spec.log import read_log

    t0 = time.perf_counter()
    log = read_log(path)
    t1 = time.perf_counter()
    ident = identify([log], IdentifyOptions(method=method))
    t2 = time.perf_counter()
    # peak memory in a separate run: tracemalloc slows allocation-heavy code several times
    tracemalloc.start()
    identify([log], IdentifyOptions(method=method))
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    return ident, t1 - t0, t2 - t1, peak, len(log.feedback)


def bench_regressor(n_samples: int = 20000):
    import pinocchio as pin

    from identification.regressor import arm_model, build_regressor
    from js2spec.robot import load_robot

    robot = load_robot("js2")
    arm = arm_model(robot.urdf_text, robot.drives)
    rng = np.random.default_rng(0)
    qm = rng.normal(size=(n_samples, 6)) * 50
    dqm = rng.normal(size=(n_samples, 6)) * 50
    ddqm = rng.normal(size=(n_samples, 6)) * 500
    t0 = time.perf_counter()
    build_regressor(arm, qm, dqm, ddqm)
    t_ours = time.perf_counter() - t0
    model = arm.model
    data = model.createData()
    K = arm.K
    q = qm @ K.T
    v = dqm @ K.T
    a = ddqm @ K.T
    t0 = time.perf_counter()
    for s in range(n_samples):
        pin.computeJointTorqueRegressor(model, data, q[s], v[s], a[s])
    t_pin = time.perf_counter() - t0
    return n_samples / t_ours, n_samples / t_pin


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--quick", action="store_true", help="growth at 1x/4x only")
    a = p.parse_args(argv)
    tmp = Path(tempfile.mkdtemp(prefix="js2_bench_id_"))
    print("js2-identify benchmark (6-axis Js-2, 500 Hz)\n")
    print("generating a 60 s simulator session (js2io trials on DirectDriveGroup) ...", flush=True)
    sess = session_60s(tmp / "session60.mcap")
    ident, t_read, t_id, peak, n = timed_identify(sess, "mixed")
    # second run: warm caches (imports, pinocchio model parsing) like a user's repeated runs
    ident, t_read2, t_id2, peak2, n = timed_identify(sess, "mixed")
    dur = n / 500.0
    print(f"1. 60 s session: {n} cycles ({dur:.1f} s), trials {ident.logs[0].trials()}, method mixed")
    tot = t_read2 + t_id2
    print(f"   read_log {t_read2:.2f} s + identify {t_id2:.2f} s = {tot:.2f} s (first run, cold imports: "
          f"{t_read + t_id:.2f} s); per 60 s of session {tot * 60 / dur:.2f} s   goal < 2 s: "
          f"{'MET' if tot * 60 / dur < 2 else 'NOT MET'}")
    print(f"   peak memory (tracemalloc, identify): {peak2 / 2**20:.0f} MiB; process max RSS "
          f"{resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MiB")
    print(f"   fit samples {ident.n_fit_samples}, RLS iterations {ident.model.rls.n_iter_}, "
          f"{ident.bp.n} base parameters, condition number {ident.condition_number:.3g}")
    ours, bare = bench_regressor()
    print(f"\n2. regressor: ours {ours:,.0f} samples/s (eq. 1 motor side, K^T Y + motor columns) vs bare pinocchio "
          f"computeJointTorqueRegressor {bare:,.0f} samples/s: ratio {ours / bare:.2f}")
    scales = [1, 4] if a.quick else [1, 4, 16]
    print("\n3. growth (synthetic eq. 1 sessions, simultaneous method):")
    print(f"   {'scale':>5} {'cycles':>8} {'read_log s':>10} {'identify s':>10} {'us/cycle':>9} {'peak MiB':>9}")
    base = None
    for sc in scales:
        path = synthetic_session(tmp / f"syn_{sc}.mcap", 60.0 * sc)
        _, tr, ti, pk, n = timed_identify(path, "simultaneous")
        per = ti / n * 1e6
        base = base or per
        print(f"   {sc:>4}x {n:>8} {tr:>10.2f} {ti:>10.2f} {per:>9.1f} {pk / 2**20:>9.0f}   "
              f"(x{per / base:.2f} per cycle vs 1x)")
        path.unlink()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
