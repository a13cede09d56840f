"""Simulator logs for the identification tests: the paper's trials on ``hil_sim.plant.Plant`` written through
``js2spec.log.LogWriter`` with the spec's events.

A stop-gap until ``js2io`` trials + ``hil_sim.direct.DirectDriveGroup`` make the same logs through the real trial
code; simple controllers (PD + gravity/inverse-dynamics feed-forward from the plant itself — the fixture may know the
truth, identification may not). One cycle: read sensors (feedback k) -> command -> step the plant one period.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from js2spec.log import LogWriter


class _Session:
    def __init__(self, plant, writer, cycle_hz):
        self.p = plant
        self.w = writer
        self.dt = 1.0 / cycle_hz
        self.k = 0
        self.n = plant.n
        self.v_est = np.zeros(self.n)
        self.q_prev = None
        self.tau = np.zeros(self.n)
        self.last = None

    @property
    def t(self):
        return self.k * self.dt

    def read(self):
        r = self.p.read_sensors()
        q = np.asarray(r.motor_position, float)
        if self.q_prev is not None:
            v = (q - self.q_prev) / self.dt
            self.v_est = 0.7 * self.v_est + 0.3 * v
        self.q_prev = q
        self.w.feedback(self.k, self.t, q, np.asarray(r.tau_motor, float),
                        motor_current=np.asarray(r.motor_current, float))
        self.last = q
        return q

    def apply(self, tau):
        self.tau = np.asarray(tau, float)
        self.w.command(self.k, self.t, [10] * self.n, self.tau)
        self.p.step(self.tau, self.dt)
        self.k += 1

    def event(self, kind, trial, **kw):
        self.w.event(self.t, kind, trial, **kw)


def _gains(plant):
    # motor-side effective inertia ~ J_a + K^2 M: PD at ~8 Hz bandwidth
    J = np.asarray(plant.truth.motor_inertia) * 3.0
    w = 2 * np.pi * 8.0
    return J * w * w, 2 * 0.8 * J * w


def _motor_of_joint(drives, q_joint):
    return np.linalg.solve(drives.gear_ratio_matrix, np.asarray(q_joint) - drives.joint_offset)


def _hold(s, q_ref_m, kp, kd, duration, drives):
    steps = int(round(duration / s.dt))
    for _ in range(steps):
        q = s.read()
        qj = drives.gear_ratio_matrix @ q + drives.joint_offset
        g = s.p.gravity_torque(qj)
        s.apply(g + kp * (q_ref_m - q) - kd * s.v_est)


def static_trial(s, drives, poses, ramp_rate=0.02, counts=3):
    kp, kd = _gains(s.p)
    cpr = np.asarray(drives.encoder_counts_per_rev, float)
    s.event("trial_start", "static")
    for pose in poses:
        qm_ref = _motor_of_joint(drives, pose)
        for m in range(s.n):
            for d in (1, -1):
                _hold(s, qm_ref, kp, kd, 0.4, drives)
                tau_m = float(s.tau[m])
                q0 = s.last[m]
                s.event("segment_start", "static", joint=m, direction=d, pose=list(map(float, pose)))
                moved = False
                for _ in range(int(3.0 / s.dt)):
                    q = s.read()
                    if abs(q[m] - q0) > counts * 2 * np.pi / cpr[m]:
                        s.event("breakaway", "static", joint=m, direction=d, value=float(s.tau[m]),
                                detail=f"{counts} counts")
                        moved = True
                        break
                    qj = drives.gear_ratio_matrix @ q + drives.joint_offset
                    tau = s.p.gravity_torque(qj) + kp * (qm_ref - q) - kd * s.v_est
                    tau_m += d * ramp_rate * s.dt
                    tau[m] = tau_m
                    s.apply(tau)
                if moved:
                    s.apply(s.tau)
                s.event("segment_end", "static", joint=m, direction=d)
    _hold(s, _motor_of_joint(drives, poses[0]), kp, kd, 0.3, drives)
    s.event("trial_end", "static")


def _track(s, drives, qm_ref, dqm_ref, ddqm_ref, kp, kd, friction_ff=True):
    q = s.read()
    tau = s.p.inverse_dynamics(q, dqm_ref, ddqm_ref)
    if friction_ff:
        tr = s.p.truth
        tau = tau + np.asarray(tr.viscous) * dqm_ref + np.asarray(tr.coulomb) * np.sign(dqm_ref)
    tau = tau + kp * (qm_ref - q) + kd * (dqm_ref - s.v_est)
    s.apply(tau)


def velocity_trial(s, drives, pose, joint_speeds=(0.15, 0.3, 0.5, 0.8), sweep=0.5, accel_time=0.15):
    """Each motor in turn at several constant speeds, both directions, over the same joint sweep."""
    kp, kd = _gains(s.p)
    K = drives.gear_ratio_matrix
    s.event("trial_start", "velocity")
    qm0 = _motor_of_joint(drives, pose)
    for m in range(s.n):
        # motor m's angular sweep: joint speed of the fastest-moved joint ~ joint_speeds
        gain = np.abs(K[:, m]).max()
        A = sweep / gain
        for js in joint_speeds:
            vm = js / gain
            for d in (1, -1):
                # start at -d*A/2, move to +d*A/2
                start = qm0.copy()
                start[m] += -d * A / 2
                _hold_track(s, drives, start, kp, kd, 0.25)
                t_acc = accel_time
                a = vm / t_acc
                T = A / vm - t_acc          # constant-speed time (distance A = vm*(T + t_acc))
                steps = int(round((2 * t_acc + T) / s.dt))
                seg_on = seg_off = None
                for i in range(steps):
                    t = i * s.dt
                    if t < t_acc:
                        acc, vel, pos = a, a * t, 0.5 * a * t * t
                    elif t < t_acc + T:
                        acc, vel, pos = 0.0, vm, 0.5 * a * t_acc ** 2 + vm * (t - t_acc)
                    else:
                        tt = t - t_acc - T
                        acc, vel = -a, vm - a * tt
                        pos = 0.5 * a * t_acc ** 2 + vm * T + vm * tt - 0.5 * a * tt * tt
                    if seg_on is None and t >= t_acc:
                        s.event("segment_start", "velocity", joint=m, direction=d, speed=float(vm))
                        seg_on = True
                    if seg_on and seg_off is None and t >= t_acc + T:
                        s.event("segment_end", "velocity", joint=m, direction=d)
                        seg_off = True
                    qr = start.copy()
                    qr[m] += d * pos
                    dqr = np.zeros(s.n)
                    dqr[m] = d * vel
                    ddqr = np.zeros(s.n)
                    ddqr[m] = d * acc
                    _track(s, drives, qr, dqr, ddqr, kp, kd, friction_ff=False)
        _hold_track(s, drives, qm0, kp, kd, 0.2)
    s.event("trial_end", "velocity")


def _hold_track(s, drives, qm_ref, kp, kd, duration):
    z = np.zeros(s.n)
    for _ in range(int(round(duration / s.dt))):
        _track(s, drives, qm_ref, z, z, kp, kd, friction_ff=False)


def accel_profile(n, duration, dt, rng, amp_joint, K, period=(0.25, 0.6)):
    """All axes at piecewise-constant angular acceleration (the paper's constant-acceleration test): per axis a
    sequence of +a, -a, -a, +a phases (velocity 0 -> +v -> 0 -> -v -> 0, back to the start) of random length and
    amplitude. Returns joint-side q, dq, ddq (N, n)."""
    N = int(round(duration / dt))
    ddq = np.zeros((N, n))
    for j in range(n):
        i = 0
        while i < N:
            T = rng.uniform(*period)
            a = amp_joint[j] * rng.uniform(0.4, 1.0) / T ** 2 * rng.choice([-1, 1])
            k = int(T / dt)
            for sgn in (1, -1, -1, 1):
                ddq[i:i + k, j] = sgn * a
                i += k
    ddq = ddq[:N]
    dq = np.cumsum(ddq, axis=0) * dt
    q = np.cumsum(dq, axis=0) * dt
    return q, dq, ddq


def motion_trial(s, drives, name, q_joint, dq_joint, ddq_joint, pose):
    kp, kd = _gains(s.p)
    Kinv = np.linalg.inv(drives.gear_ratio_matrix)
    qm0 = _motor_of_joint(drives, pose)
    s.event("trial_start", name)
    _hold_track(s, drives, qm0, kp, kd, 0.3)
    s.event("segment_start", name)
    for i in range(len(q_joint)):
        _track(s, drives, qm0 + Kinv @ q_joint[i], Kinv @ dq_joint[i], Kinv @ ddq_joint[i], kp, kd)
    s.event("segment_end", name)
    _hold_track(s, drives, qm0 + Kinv @ q_joint[-1], kp, kd, 0.2)
    s.event("trial_end", name)


def make_session(path: str | Path, robot=None, trials=("static", "velocity", "acceleration", "validation"),
                 accel_s: float = 30.0, valid_s: float = 8.0, seed: int = 0, truth=None, effects=None) -> Path:
    """Write one js2 log with the requested trials from the simulator (true parameters: the robot's sim_truth)."""
    from js2spec.robot import load_robot
    from hil_sim.plant import Plant

    robot = robot or load_robot("js2")
    drives = robot.drives
    plant = Plant(robot, truth=truth, seed=seed, effects=effects)
    cycle_hz = float(drives.cycle_hz or 500.0)
    pose = np.array([0.0, 0.3, -0.6, 0.0, 0.5, 0.0])[:drives.n]
    plant.reset(pose)
    rng = np.random.default_rng(seed + 11)
    path = Path(path)
    amp = np.array([0.6, 0.35, 0.45, 0.8, 0.6, 0.9])[:drives.n]
    with LogWriter(path, robot=robot.name, cycle_hz=cycle_hz, source="hil_sim:tests fixture", urdf_text=robot.urdf_text,
                   drives_yaml=robot.drives_yaml) as w:
        s = _Session(plant, w, cycle_hz)
        if "static" in trials:
            static_trial(s, drives, [pose, pose + np.array([0.4, -0.2, 0.3, 0.5, -0.3, 0.6])[:drives.n]])
        if "velocity" in trials:
            velocity_trial(s, drives, pose)
        if "acceleration" in trials:
            q, dq, ddq = accel_profile(drives.n, accel_s, s.dt, rng, amp, drives.gear_ratio_matrix)
            motion_trial(s, drives, "acceleration", q, dq, ddq, pose)
        if "validation" in trials:
            t = np.arange(int(valid_s / s.dt)) * s.dt
            q = np.zeros((len(t), drives.n))
            dq = np.zeros_like(q)
            ddq = np.zeros_like(q)
            for j in range(drives.n):
                for h, f in enumerate((0.3, 0.7, 1.3)):
                    A = amp[j] * 0.4 / (h + 1)
                    ph = rng.uniform(0, 2 * np.pi)
                    w_ = 2 * np.pi * f
                    q[:, j] += A * (np.sin(w_ * t + ph) - np.sin(ph))
                    dq[:, j] += A * w_ * np.cos(w_ * t + ph)
                    ddq[:, j] += -A * w_ * w_ * np.sin(w_ * t + ph)
            # start at rest: ramp the motion in over 1 s
            ramp = np.clip(t / 1.0, 0, 1)
            ramp = ramp * ramp * (3 - 2 * ramp)
            dr = np.gradient(ramp, s.dt)
            ddr = np.gradient(dr, s.dt)
            q2 = q * ramp[:, None]
            dq2 = dq * ramp[:, None] + q * dr[:, None]
            ddq2 = ddq * ramp[:, None] + 2 * dq * dr[:, None] + q * ddr[:, None]
            motion_trial(s, drives, "validation", q2, dq2, ddq2, pose)
    return path
