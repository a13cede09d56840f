"""Shared helpers of the simulator tests: robot variants and the paper's test procedures run on the plant.

The helpers compute everything they compare against with their OWN pinocchio model built from the URDF text
(never the plant's), so a mistake in the plant's dynamics cannot cancel out.
"""
from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pinocchio as pin
import yaml

from js2spec.robot import BUILTIN_CONFIGS, load_robot

JS2 = BUILTIN_CONFIGS / "js2"

#: a TX40-style coupled wrist (non-symmetric): joint 6 also turns with motor 5
K_TX40 = np.diag([0.01, 0.01, 0.0125, 0.02, 0.01, 0.0125])
K_TX40[5, 4] = 0.004


def make_robot(tmp_path: Path, K=None, truth_changes: dict | None = None, drives_changes: dict | None = None):
    """A copy of configs/js2 in ``tmp_path`` with another K / sim_truth / drives values; returns RobotConfig."""
    folder = Path(tmp_path) / "robot"
    if folder.exists():
        shutil.rmtree(folder)
    shutil.copytree(JS2, folder)
    drives = yaml.safe_load((folder / "drives.yaml").read_text())
    if K is not None:
        drives["gear_ratio_matrix"] = np.asarray(K).tolist()
    drives.update(drives_changes or {})
    (folder / "drives.yaml").write_text(yaml.safe_dump(drives))
    truth = yaml.safe_load((folder / "sim_truth.yaml").read_text())
    truth.update(truth_changes or {})
    (folder / "sim_truth.yaml").write_text(yaml.safe_dump(truth))
    return load_robot(folder)


def js2():
    return load_robot("js2")


def truth_yaml(robot) -> dict:
    return yaml.safe_load(Path(robot.sim_truth_path).read_text())


class Reference:
    """Independent eq. 1 terms from the URDF text (own pinocchio model, gravity -z 9.81)."""

    def __init__(self, robot, payload=None):
        self.model = pin.buildModelFromXML(robot.urdf_text)
        self.model.gravity.linear = np.array([0.0, 0.0, -9.81])
        if payload is not None:     # (joint index, mass, com)
            j, m, c = payload
            jid = self.model.getJointId(robot.drives.joints[j])
            self.model.inertias[jid] = self.model.inertias[jid] + pin.Inertia(m, np.asarray(c), np.zeros((3, 3)))
        self.data = self.model.createData()
        self.K = np.asarray(robot.drives.gear_ratio_matrix, dtype=float)
        self.offset = np.asarray(robot.drives.joint_offset, dtype=float)
        t = truth_yaml(robot)
        n = robot.drives.n
        self.Ja = np.broadcast_to(np.asarray(t["motor_inertia"], dtype=float), (n,))
        self.B = np.broadcast_to(np.asarray(t["viscous"], dtype=float), (n,))
        self.fc = np.broadcast_to(np.asarray(t["coulomb"], dtype=float), (n,))
        self.fs = np.broadcast_to(np.asarray(t["static"], dtype=float), (n,))

    def q_joint(self, q_motor):
        return self.K @ q_motor + self.offset

    def motor_torque(self, q_motor, dq_motor, ddq_motor, friction=True):
        """Eq. 1: K^T rnea(q, qd, qdd) + J_a theta_m_dd (+ B theta_m_d + f_c sgn theta_m_d)."""
        q, v, a = self.q_joint(q_motor), self.K @ dq_motor, self.K @ ddq_motor
        tau = self.K.T @ pin.rnea(self.model, self.data, q, v, a) + self.Ja * ddq_motor
        if friction:
            tau = tau + self.B * dq_motor + self.fc * np.sign(dq_motor)
        return tau

    def motor_inertia_matrix(self, q_joint):
        """Motor-side inertia ``K^T M(q) K + diag(J_a)``."""
        M = pin.crba(self.model, self.data, np.asarray(q_joint, dtype=float))
        M = np.triu(M) + np.triu(M, 1).T
        return self.K.T @ M @ self.K + np.diag(self.Ja)

    def gravity_motor(self, q_joint):
        """Motor-side gravity ``K^T g(q)`` (eq. 2-4)."""
        return self.K.T @ pin.computeGeneralizedGravity(self.model, self.data, np.asarray(q_joint, dtype=float))

    def energy(self, q_motor, dq_motor):
        q, v = self.q_joint(q_motor), self.K @ dq_motor
        pin.forwardKinematics(self.model, self.data, q, v)
        M = pin.crba(self.model, self.data, q)
        M = np.triu(M) + np.triu(M, 1).T
        kinetic = 0.5 * v @ M @ v + 0.5 * np.sum(self.Ja * dq_motor ** 2)
        # potential: sum of m g z_com over links, from the links' placements
        pin.updateFramePlacements(self.model, self.data)
        potential = 0.0
        for jid in range(1, self.model.njoints):
            inert = self.model.inertias[jid]
            com_world = self.data.oMi[jid].act(inert.lever)
            potential += inert.mass * 9.81 * com_world[2]
        return kinetic, potential


def breakaway(plant, axis, hold, direction, rate=0.01, dt=0.002, t_max=20.0, start=None):
    """Eq. 2-3 static test on the plant: ramp motor torque on ``axis`` (others at ``hold``) until its encoder
    moves by one count; return the commanded torque at that moment (tau+ or tau-)."""
    tau = np.array(hold, dtype=float)
    if start is not None:
        tau[axis] = start
    c0 = plant.read_sensors().encoder_counts[axis]
    steps = int(t_max / dt)
    for _ in range(steps):
        tau[axis] += direction * rate * dt
        plant.step(tau, dt)
        if plant.read_sensors().encoder_counts[axis] != c0:
            return tau[axis]
    raise AssertionError(f"axis {axis} never broke away (last torque {tau[axis]})")


def constant_speed(plant, ref, axis, speed, q0=None, settle=0.3, measure=0.25, dt=0.002, bandwidth=100.0,
                   hold_gravity=True, record=None, ramp=0.0):
    """Eq. 5 constant angular velocity test: a velocity PI loop on motor ``axis`` (gravity feed-forward from the
    reference model, gains scaled to the axis' inertia), the other axes held by stiction against their gravity torque. Returns (mean motor speed
    from the encoder, mean measured torque minus gravity) over the measuring window."""
    plant.reset(q0)
    inertia = ref.motor_inertia_matrix(plant.q_joint)[axis, axis]
    kp = bandwidth * inertia                 # PI: closed-loop bandwidth ~ `bandwidth` rad/s, zero at bandwidth/3
    ki = kp * bandwidth / 3
    integ = 0.0
    n = plant.n
    speeds, torques = [], []
    pos0 = None
    for k in range(int((settle + measure) / dt)):
        q_joint = plant.q_joint
        g = ref.gravity_motor(q_joint) if hold_gravity else np.zeros(n)
        ref_speed = speed * min(1.0, (k + 1) * dt / ramp) if ramp > 0 else speed
        err = ref_speed - plant.dq_motor[axis]
        integ += ki * err * dt
        tau = g.copy()
        tau[axis] = g[axis] + kp * err + integ + np.sign(speed) * ref.fc[axis]
        plant.step(tau, dt)
        r = plant.read_sensors()
        if record is not None:
            record.append((plant.t, r, tau.copy()))
        if k * dt >= settle:
            if pos0 is None:
                pos0, t0 = r.motor_position[axis], plant.t
            # gravity at the measured pose (encoder angles through K), eq. 5 subtracts it
            g_meas = ref.gravity_motor(ref.q_joint(r.motor_position)) if hold_gravity else np.zeros(n)
            torques.append(r.tau_motor[axis] - g_meas[axis])
    w = (r.motor_position[axis] - pos0) / (plant.t - t0)
    return w, float(np.mean(torques))
