#!/usr/bin/env python3
"""Speed of the simulator's physics: simulated seconds per wall second for the 6-DOF plant at 500 Hz.

Per sample (2 ms): ``plant.step(tau, 0.002)`` + ``plant.read_sensors()``, with realistic torques: a joint PD loop
with gravity feed-forward tracking slow sinusoids on all six axes (the acquisition's constant-acceleration trial
looks like this), torques clipped to drives.yaml's limits. The controller runs outside the timed calls.
The same run times bare ``pinocchio.aba`` on the visited states and prints the plant's cost as a ratio to it.

Scenarios: ``moving`` (all axes sliding, the fast path), ``holding`` (all axes stuck at a pose: stiction
time-stepping, general path), ``effects`` (moving with Stribeck + cogging, Python force terms), ``elastic``
(moving with an elastic joint 2: extra coordinate, CRBA + solve, smaller step).

    .venv/bin/python scripts/bench_sim.py [--seconds 10] [--robot js2]
"""
from __future__ import annotations

import argparse
import time

import numpy as np
import pinocchio as pin

from hil_sim.plant import Plant
from js2spec.robot import load_robot

DT = 0.002


def run(robot, scenario: str, seconds: float):
    effects = None
    if scenario == "effects":
        effects = [{"kind": "stribeck", "joints": [0, 1, 2], "velocity": 5.0},
                   {"kind": "cogging", "joints": [3, 4, 5], "amplitude": 0.002, "periods_per_rev": 6}]
    elif scenario == "elastic":
        effects = [{"kind": "joint_elasticity", "joints": [1], "stiffness": 5000.0, "damping": 10.0}]
    plant = Plant(robot, seed=0, effects=effects)
    drives = robot.drives
    n = plant.n
    q0 = np.array([0.0, 0.3, -0.5, 0.0, 0.4, 0.0])
    plant.reset(q0)
    limit = drives.torque_limit if drives.torque_limit is not None else np.full(n, np.inf)
    amp = np.array([0.8, 0.4, 0.5, 1.0, 0.6, 1.2])
    freq = np.array([0.13, 0.21, 0.17, 0.29, 0.31, 0.37])       # Hz
    wn = 2 * np.pi * 6.0                                          # PD bandwidth, rad/s
    K = drives.K
    t_step = t_read = 0.0
    states = []
    samples = int(round(seconds / DT))
    q_prev = drives.joint_from_motor(plant.read_sensors().motor_position)
    for k in range(samples):
        t = k * DT
        if scenario == "holding":
            q_des, qd_des = q0, np.zeros(n)
        else:
            q_des = q0 + amp * np.sin(2 * np.pi * freq * t)
            qd_des = amp * 2 * np.pi * freq * np.cos(2 * np.pi * freq * t)
        r_q = q_prev
        if k % 50 == 0:
            M = plant.dyn.mass_matrix_z(plant.dyn.q_link(plant._z))[:n, :n]     # motor-side inertia, for gains
            m_joint = np.diag(np.linalg.inv(K).T @ M @ np.linalg.inv(K))
        g = plant.gravity_torque(r_q) if k % 5 == 0 or k == 0 else g
        if scenario == "holding":
            tau = g
        else:
            qd = (r_q - states[-1][0]) / DT if states else np.zeros(n)
            tau_joint = m_joint * (wn ** 2 * (q_des - r_q) + 2 * wn * (qd_des - qd))
            tau = np.clip(g + K.T @ tau_joint, -limit, limit)
        t0 = time.perf_counter()
        plant.step(tau, DT)
        t1 = time.perf_counter()
        reading = plant.read_sensors()
        t2 = time.perf_counter()
        t_step += t1 - t0
        t_read += t2 - t1
        q_prev = drives.joint_from_motor(reading.motor_position)
        states.append((r_q, plant.q_joint, plant.dq_joint, tau))
    # bare pinocchio ABA on the visited states (same run, same machine state)
    model = pin.buildModelFromXML(robot.urdf_text)
    data = model.createData()
    sel = states[:: max(1, len(states) // 2000)]
    reps = 10
    t0 = time.perf_counter()
    for _ in range(reps):
        for _, q, v, tau in sel:
            pin.aba(model, data, q, v, tau)
    t_aba = (time.perf_counter() - t0) / (reps * len(sel))
    substeps = int(np.ceil(DT / plant.h_max - 1e-9))
    per_sample = (t_step + t_read) / samples
    travel = np.ptp(np.array([s[1] for s in states]), axis=0)
    return {"scenario": scenario, "sim_per_wall": DT / per_sample, "us_sample": per_sample * 1e6,
            "us_step": t_step / samples * 1e6, "us_read": t_read / samples * 1e6, "substeps": substeps,
            "us_aba": t_aba * 1e6, "ratio_sample": per_sample / t_aba,
            "ratio_substep": t_step / samples / substeps / t_aba, "travel": travel,
            "fast_path": plant.dyn.fast}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=10.0, help="simulated seconds per scenario")
    ap.add_argument("--robot", default="js2")
    ap.add_argument("--scenarios", default="moving,holding,effects,elastic")
    args = ap.parse_args(argv)
    robot = load_robot(args.robot)
    print(f"{args.robot}: 6-DOF plant at 500 Hz (step(tau, 2 ms) + read_sensors per sample), "
          f"{args.seconds:g} simulated s per scenario")
    print(f"{'scenario':9s} {'sim s/wall s':>12s} {'us/sample':>9s} {'step':>6s} {'read':>5s} {'substeps':>8s} "
          f"{'ABA us':>6s} {'sample/ABA':>10s} {'substep/ABA':>11s}  joint travel (rad)")
    results = []
    for sc in args.scenarios.split(","):
        r = run(robot, sc, args.seconds)
        results.append(r)
        print(f"{sc:9s} {r['sim_per_wall']:12.1f} {r['us_sample']:9.1f} {r['us_step']:6.1f} {r['us_read']:5.1f} "
              f"{r['substeps']:8d} {r['us_aba']:6.2f} {r['ratio_sample']:10.1f} {r['ratio_substep']:11.1f}  "
              f"{np.array2string(r['travel'], precision=2)}")
    main_r = results[0]
    goal = 50.0
    verdict = "meets" if main_r["sim_per_wall"] >= goal else "MISSES"
    print(f"\n{main_r['scenario']}: {main_r['sim_per_wall']:.0f}x real time ({verdict} the {goal:.0f}x goal; "
          f"{1e6 * DT / goal:.0f} us per 2 ms sample allowed, {main_r['us_sample']:.1f} us used)")
    if main_r["sim_per_wall"] < goal:
        print("limit: per-sample Python/numpy call overhead (see step/read split above)")


if __name__ == "__main__":
    main()
