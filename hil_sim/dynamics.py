"""Rigid-body + motor dynamics of eq. 1 in generalized coordinates, with pinocchio.

Generalized coordinates ``z = [theta_m (n motor angles), delta (one deflection per elastic joint)]`` with the
constant map to the link (joint-side) angles of the URDF::

    q_link = J z + offset,   J = [K | E]      (E picks the elastic joints; without elasticity q_link = K theta_m + offset)

Kinetic energy ``1/2 v^T M(q) v + 1/2 theta_m_d^T J_a theta_m_d`` gives the equations of motion::

    M_z z_dd + J^T nle(q, v) = Q,      M_z = J^T M(q) J + diag(J_a, 0)

where ``nle = h(q, q_d) q_d + g(q)`` (eq. 1's Coriolis/centrifugal and gravity terms), and ``Q`` holds the motor
torques minus friction (motor rows) and the spring-damper torques (deflection rows). Without elasticity the motor
rows are exactly eq. 1: ``tau_m = K^T (M q_dd + h q_d + g) + J_a theta_m_dd + friction``.

Fast path: without deflections and when the reflected motor inertia ``A = K^-T diag(J_a) K^-1`` is diagonal (it is
for uncoupled gears and for a symmetric differential wrist with equal ``J_a``), eq. 1 is ``(M + A) q_dd + nle =
K^-T (tau_m - f)``, i.e. pinocchio's ABA with ``armature = diag(A)``: one O(n) call, no matrix solve.
Otherwise (coupled non-symmetric K, elastic joints, stuck axes) the general path builds ``M_z`` with CRBA and solves.

The model's data kept apart: ``ArmDynamics`` holds pinocchio models and constant matrices; the state lives in
:class:`hil_sim.plant.Plant`.
"""
from __future__ import annotations

import numpy as np
import pinocchio as pin

from js2spec.errors import ConfigError

GRAVITY = np.array([0.0, 0.0, -9.81])


def build_model(urdf_text: str, source=None) -> pin.Model:
    """Pinocchio model of the URDF (fixed base, gravity -z, 9.81 m/s^2)."""
    try:
        model = pin.buildModelFromXML(urdf_text)
    except Exception as exc:  # pinocchio raises plain RuntimeError/ValueError on bad URDF
        raise ConfigError(source, None, f"pinocchio cannot build a model from the URDF ({exc})") from None
    model.gravity.linear = GRAVITY.copy()
    return model


class ArmDynamics:
    """Constant model of the arm: pinocchio model(s), K, J, J_a, elastic joints; forward and inverse dynamics.

    Joint-space quantities passed to pinocchio are in the URDF's (pinocchio's) joint order; ``perm`` maps drive
    order to it (``q_pin = P q_joint``), folded into ``K`` so the hot loop pays nothing for it.
    """

    def __init__(self, urdf_text: str, drives, motor_inertia, elastic_joints=(), payloads=(), source=None,
                 effects_source=None, gear_ratio_matrix=None):
        """``payloads``: ``(index in the effects list, payload_change Effect)`` pairs; errors in them name
        ``effects_source`` (the sim_truth file) and ``effects[index].mass``. ``gear_ratio_matrix``: the arm's true
        joint-from-motor matrix when it differs from ``drives.yaml``'s K (a ``coupling`` effect); every map
        between motors and links here (angles ``q = K theta_m``, torques ``K^T tau``, the mass matrix) uses it."""
        model = build_model(urdf_text, source)
        n = drives.n
        names = list(drives.joints)
        P = np.zeros((n, n))
        for i, name in enumerate(names):
            if not model.existJointName(name):
                raise ConfigError(source, "joint", f"drive joint {name!r} is not a joint of the URDF")
            jid = model.getJointId(name)
            if model.joints[jid].nq != 1 or model.joints[jid].nv != 1:
                raise ConfigError(source, f"joint[{name}]", "only 1-dof (revolute/prismatic) joints are supported")
            P[model.joints[jid].idx_q, i] = 1.0
        if model.nq != n:
            raise ConfigError(source, "joint", f"URDF has {model.nq} dof, drives.yaml {n} drives")
        for index, e in payloads:
            for j in e.joints:
                jid = model.getJointId(names[j])
                add = pin.Inertia(float(e["mass"]), np.asarray(e["com"], dtype=float),
                                  np.diag(np.asarray(e["inertia"], dtype=float)))
                new = model.inertias[jid] + add
                if not new.mass > 0:
                    raise ConfigError(effects_source, f"effects[{index}].mass",
                                      f"link of joint {names[j]} would have mass {new.mass:.4g} kg (must stay > 0)")
                model.inertias[jid] = new
        self.model = model
        self.data = model.createData()
        # some pinocchio versions fill only the upper triangle of M: check once, symmetrise only if needed
        probe = pin.crba(model, model.createData(), pin.randomConfiguration(model, -np.ones(model.nq),
                                                                             np.ones(model.nq)))
        self._crba_full = bool(np.array_equal(probe, probe.T))
        self.n = n
        self.perm = P
        self.joint_names = names
        K = np.asarray(drives.gear_ratio_matrix if gear_ratio_matrix is None else gear_ratio_matrix, dtype=float)
        self.K_drive = K
        self.Kp = P @ K                                    # q_pin = Kp theta_m + off_p
        self.Kp_inv = np.linalg.inv(self.Kp)
        self.Kp_inv_T = self.Kp_inv.T.copy()
        self.Kp_T = self.Kp.T.copy()
        self.off_p = P @ np.asarray(drives.joint_offset, dtype=float)
        self.motor_inertia = np.asarray(motor_inertia, dtype=float).copy()
        self.elastic = [int(j) for j in elastic_joints]     # drive indices of elastic joints
        e = self.ne = len(self.elastic)
        self.nz = n + e
        E = np.zeros((n, e))
        for c, j in enumerate(self.elastic):
            E[:, c] = P[:, j]
        self.J = np.hstack([self.Kp, E])
        self.J_T = self.J.T.copy()
        self.Ja_z = np.concatenate([self.motor_inertia, np.zeros(e)])
        A = self.Kp_inv_T @ np.diag(self.motor_inertia) @ self.Kp_inv
        off_diag = A - np.diag(np.diag(A))
        self.fast = e == 0 and np.max(np.abs(off_diag)) <= 1e-12 * np.max(np.abs(A))
        self.model_arm = None
        if self.fast:
            self.model_arm = model.copy()
            self.model_arm.armature = np.diag(A).copy()
            self.data_arm = self.model_arm.createData()

    # ------------------------------------------------------------------ kinematic maps
    def q_link(self, z: np.ndarray) -> np.ndarray:
        """Link angles (pinocchio order) of generalized coordinates ``z``."""
        return self.J @ z + self.off_p

    def z_from_link(self, q_pin: np.ndarray, delta: np.ndarray | None = None) -> np.ndarray:
        """Generalized coordinates with link angles ``q_pin`` and deflections ``delta`` (default 0)."""
        delta = np.zeros(self.ne) if delta is None else np.asarray(delta, dtype=float)
        gear = q_pin - (self.J[:, self.n:] @ delta if self.ne else 0.0)
        return np.concatenate([self.Kp_inv @ (gear - self.off_p), delta])

    # ------------------------------------------------------------------ dynamics
    def mass_matrix_z(self, q_pin: np.ndarray) -> np.ndarray:
        """``M_z = J^T M(q) J + diag(J_a, 0)``."""
        M = pin.crba(self.model, self.data, q_pin)
        if not self._crba_full:
            M = np.triu(M) + np.triu(M, 1).T
        return self.J_T @ M @ self.J + np.diag(self.Ja_z)

    def solve(self, z, zd, Q, stuck=None):
        """Accelerations ``z_dd`` from ``M_z z_dd = Q - J^T nle``; axes in ``stuck`` (bool, n) held at zero
        acceleration. Returns ``(z_dd, lam)`` with ``lam`` (n) the extra motor torque that holds the stuck axes
        (the friction they need, sign: opposing a positive drive), 0 elsewhere."""
        q = self.J @ z + self.off_p
        v = self.J @ zd
        Mz = self.mass_matrix_z(q)
        rhs = Q - self.J_T @ pin.nonLinearEffects(self.model, self.data, q, v)
        lam = np.zeros(self.n)
        if stuck is None or not stuck.any():
            return np.linalg.solve(Mz, rhs), lam
        S = np.concatenate([stuck, np.zeros(self.ne, dtype=bool)])
        F = ~S
        a = np.zeros(self.nz)
        if F.any():
            a[F] = np.linalg.solve(Mz[np.ix_(F, F)], rhs[F])
        lam[stuck] = rhs[S] - Mz[np.ix_(S, F)] @ a[F]
        return a, lam

    def solve_fast(self, z, zd, Q, stuck=None):
        """As :meth:`solve` for the fast path (rigid, diagonal reflected armature ``A``).

        Nothing stuck: ABA with armature, O(n). A few axes stuck: the constraint through the inverse inertia
        (pinocchio ``computeMinverse``)::

            a0 = M_z^-1 rhs,   M_z^-1[S,S] lam_S = a0[S],   a = a0 - M_z^-1[:,S] lam_S   (a[S] = 0)

        Most axes stuck (the sequential tests: one axis moves, the others are held): the reduced system
        ``M_z[F,F] a_F = rhs_F``, ``lam_S = rhs_S - M_z[S,F] a_F`` with ``M_z = K^T (M + A) K`` (CRBA)."""
        q = self.Kp @ z + self.off_p
        lam = np.zeros(self.n)
        if stuck is None or not stuck.any():
            return self.Kp_inv @ pin.aba(self.model_arm, self.data_arm, q, self.Kp @ zd, self.Kp_inv_T @ Q), lam
        S = np.flatnonzero(stuck)
        if 2 * len(S) > self.n:
            F = np.flatnonzero(~stuck)
            M = pin.crba(self.model_arm, self.data_arm, q)
            if not self._crba_full:
                M = np.triu(M) + np.triu(M, 1).T
            Mz = self.Kp_T @ M @ self.Kp
            rhs = Q - self.Kp_T @ pin.nonLinearEffects(self.model_arm, self.data_arm, q, self.Kp @ zd)
            a = np.zeros(self.n)
            if len(F) == 0:
                lam[S] = rhs[S]
            elif len(F) == 1:
                f = F[0]
                a[f] = rhs[f] / Mz[f, f]
                lam[S] = rhs[S] - Mz[S, f] * a[f]
            else:
                a[F] = np.linalg.solve(Mz[np.ix_(F, F)], rhs[F])
                lam[S] = rhs[S] - Mz[np.ix_(S, F)] @ a[F]
            return a, lam
        a = self.Kp_inv @ pin.aba(self.model_arm, self.data_arm, q, self.Kp @ zd, self.Kp_inv_T @ Q)
        Minv = self.Kp_inv @ pin.computeMinverse(self.model_arm, self.data_arm, q) @ self.Kp_inv_T
        if len(S) == 1:
            s = S[0]
            lam_s = a[s] / Minv[s, s]
            a = a - Minv[:, s] * lam_s
            lam[s] = lam_s
        else:
            lam_S = np.linalg.solve(Minv[np.ix_(S, S)], a[S])
            a = a - Minv[:, S] @ lam_S
            lam[S] = lam_S
        a[S] = 0.0
        return a, lam

    def inverse_dynamics(self, q_motor, dq_motor, ddq_motor) -> np.ndarray:
        """Eq. 1 without friction: ``tau_m = K^T rnea(q, q_d, q_dd) + J_a theta_m_dd`` (rigid joints)."""
        q_motor, dq_motor, ddq_motor = (np.asarray(x, dtype=float) for x in (q_motor, dq_motor, ddq_motor))
        q = self.Kp @ q_motor + self.off_p
        tau_j = pin.rnea(self.model, self.data, q, self.Kp @ dq_motor, self.Kp @ ddq_motor)
        return self.Kp.T @ tau_j + self.motor_inertia * ddq_motor

    def gravity_link(self, q_pin: np.ndarray) -> np.ndarray:
        """``g(q)`` (pinocchio order)."""
        return pin.computeGeneralizedGravity(self.model, self.data, q_pin).copy()

    def kinetic_energy(self, z, zd) -> float:
        """Links (pinocchio) plus rotors ``1/2 J_a theta_m_d^2``."""
        q, v = self.J @ z + self.off_p, self.J @ zd
        ek = pin.computeKineticEnergy(self.model, self.data, q, v)
        return float(ek + 0.5 * np.sum(self.motor_inertia * zd[: self.n] ** 2))

    def potential_energy(self, z) -> float:
        """Gravity potential of the links (pinocchio, 0 at z_world = 0)."""
        return float(pin.computePotentialEnergy(self.model, self.data, self.J @ z + self.off_p))
