"""The simulated arm: eq. 1 on the motor side, stiction, effects, sensors; stepped with motor torques.

```python
plant = Plant(load_robot("js2"))               # truth: configs/js2/sim_truth.yaml
plant.reset(q_joint=None)                      # at rest
plant.step(tau_motor, 0.002)                   # motor-shaft torque held for 2 ms
r = plant.read_sensors()                       # encoder counts, motor position, current, kt*current
```

Integration (fixed step ``h = 1/(cycle_hz * substeps)``, 1 ms by default; ``step(duration)`` uses
``ceil(duration/h)`` equal steps): the midpoint ("leapfrog", position Verlet) scheme, 2nd order, ONE dynamics
evaluation per step::

    z_mid = z + h/2 v,    a = a(z_mid, v + h/2 a_prev),    v' = v + h a,    z' = z_mid + h/2 v'

(``a_prev`` the previous step's acceleration extrapolates the mid-step velocity for the velocity-dependent terms;
it is dropped after a stop.) Why this one: semi-implicit Euler is 1st order (energy error ~1e-3 over 10 s at
0.5 ms on the Js-2); Heun/RK2 needs two evaluations per step once the torque changes every sample (it does in a
closed loop); RK4 needs four. The midpoint scheme is time-symmetric, keeps the frictionless Js-2's energy within ~2e-5 (relative to the kinetic energy exchanged) over
10 s at 1 ms, and evaluates the torque at mid-step, so a new torque each sample costs nothing extra.

Friction with real stiction (time-stepping with a stuck set): in each step every axis with dry friction that is
at rest is a stuck candidate; the dynamics (at the step's midpoint) are solved with the candidates' accelerations
held at zero, which gives the friction ``lambda`` each needs; axes whose ``|lambda|`` exceeds ``f_s`` (eq. 2-3) are released
(moving in the direction of ``lambda``, with Coulomb friction) and the rest re-solved until consistent. Sliding
axes carry the friction sign of their velocity for the whole step; an axis whose velocity would cross zero in a
step stops there (velocity set to 0) and is a candidate at the next step.

Reported joint angles (``q_joint``) are the link angles; with elastic joints they differ from the gear output
``K theta_m + offset`` by the deflection. The encoders see the motors only. With a ``coupling`` effect the arm's
gear matrix is ``K_true`` (:meth:`Plant._true_gear_matrix`), used for all the physics; ``drives.yaml``'s K stays
what the drives and the identified model use.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pinocchio as pin

from js2spec.errors import ConfigError

from .dynamics import ArmDynamics
from .effects import Effect, parse_effects
from .friction import Friction
from .sensors import SensorReading, Sensors
from .truth import SimTruth, load_truth

__all__ = ["Plant", "SensorReading"]

#: largest (natural frequency x step) for elastic joints: the step shrinks so that stiff springs stay accurate
#: (leapfrog phase error ~ (w h)^2 / 24, 0.2 % at 0.2; stability would allow up to 2)
MAX_OMEGA_H = 0.2


class Plant:
    """The Js-2 (or any configured arm) as physics: state, ``step``, ``read_sensors``, ``inverse_dynamics``."""

    def __init__(self, robot, truth: SimTruth | str | Path | None = None, seed: int | None = None,
                 effects: list | None = None):
        self.robot = robot
        drives = robot.drives
        n = self.n = drives.n
        if truth is None:
            truth = load_truth(robot)
        elif not isinstance(truth, SimTruth):
            truth = load_truth(truth, n)
        effects_source = truth.source
        if effects is not None:
            effects_source = "Plant(effects=...)"
            effects = parse_effects(effects, n, source=effects_source, joints=list(drives.joints))
            truth = truth.replace(effects=tuple(effects))
        if truth.n != n:
            raise ConfigError(truth.source, "motor_inertia", f"has {truth.n} drives, drives.yaml {n}")
        self.truth = truth
        effects = list(truth.effects)
        self.effects = effects

        # --- elastic joints (joint_elasticity and/or backlash): one deflection coordinate each
        elastic: dict[int, dict] = {}
        for e in effects:
            if e.kind in ("joint_elasticity", "backlash"):
                for j in e.joints:
                    s = elastic.setdefault(j, {"k": None, "d": None, "width": 0.0})
                    if e.kind == "backlash":
                        s["width"] = e["width"]
                        if e["stiffness"] is not None:
                            s["k"] = e["stiffness"]
                        if e["damping"] is not None:
                            s["d"] = e["damping"]
                    else:
                        s["k"] = e["stiffness"] if s["k"] is None else s["k"]
                        s["d"] = e["damping"] if s["d"] is None else s["d"]
        self.elastic_joints = sorted(elastic)
        self.spring_k = np.array([elastic[j]["k"] for j in self.elastic_joints], dtype=float)
        self.spring_d = np.array([elastic[j]["d"] or 0.0 for j in self.elastic_joints], dtype=float)
        self.spring_half = np.array([elastic[j]["width"] / 2 for j in self.elastic_joints], dtype=float)

        self.gear_ratio_matrix = self._true_gear_matrix(drives, effects, effects_source)
        self.dyn = ArmDynamics(robot.urdf_text, drives, truth.motor_inertia, self.elastic_joints,
                               [(i, e) for i, e in enumerate(effects) if e.kind == "payload_change"],
                               source=robot.urdf_path, effects_source=effects_source,
                               gear_ratio_matrix=self.gear_ratio_matrix)
        self.friction = Friction(truth.viscous, truth.coulomb, truth.static, effects)

        self.load_offset = np.zeros(n)          # torque_offset: a constant load torque on each motor (N*m)
        for e in effects:
            if e.kind == "torque_offset":
                self.load_offset[list(e.joints)] += e["offset"]
        self.has_load_offset = bool(np.any(self.load_offset))
        cog = [e for e in effects if e.kind == "cogging"]
        self.cog_axes = np.array([j for e in cog for j in e.joints], dtype=int)
        self.cog_amp = np.array([e["amplitude"] for e in cog for _ in e.joints], dtype=float)
        self.cog_periods = np.array([e["periods_per_rev"] for e in cog for _ in e.joints], dtype=float)
        self.cog_phase = np.array([e["phase"] for e in cog for _ in e.joints], dtype=float)
        self.has_cogging = len(self.cog_axes) > 0

        self.seed = truth.seed if seed is None else seed
        self.sensors = Sensors(drives, truth.current_noise_std, np.random.default_rng(self.seed))
        self.cycle_hz = float(drives.cycle_hz or 500.0)
        self.h_max = 1.0 / (self.cycle_hz * truth.substeps)
        if self.dyn.ne:
            self.h_max = min(self.h_max, MAX_OMEGA_H / self._max_spring_omega())

        # fast path applies when rigid, armature diagonal and no position/velocity-dependent extras
        self._simple = (self.dyn.fast and not self.has_cogging and not self.friction.has_stribeck
                        and self.friction.constant)
        self._active = self.friction.active.copy()
        self._any_active = bool(self._active.any())
        self._all_stuck_rigid = self.dyn.ne == 0
        self._lam = np.zeros(n)
        self._Qm = np.zeros(self.dyn.nz)
        self._viscous_j = self.dyn.Kp_inv_T * self.friction.viscous        # K^-T diag(B), motor velocity in
        self.reset()

    @staticmethod
    def _true_gear_matrix(drives, effects, source) -> np.ndarray:
        """The arm's joint-from-motor matrix: ``drives.yaml``'s K, or with ``coupling`` effects
        ``K_true = (I + sum c e_j e_i^T) K`` (joint j turns c rad more per rad of joint i). The physics (link angles
        and velocities from the motors, motor torques ``K_true^T tau`` from the links, hence power
        ``tau_m . theta_m_d = tau . q_d``) uses it; the encoders still read the motors and the drives still use K."""
        K = np.asarray(drives.gear_ratio_matrix, dtype=float)
        couplings = [(i, e) for i, e in enumerate(effects) if e.kind == "coupling"]
        if not couplings:
            return K
        C = np.eye(len(K))
        for _, e in couplings:
            for j in e.joints:
                C[j, e["from_joint"]] += e["coefficient"]
        if abs(np.linalg.det(C)) < 1e-6:
            raise ConfigError(source, f"effects[{couplings[-1][0]}].coefficient",
                              "the couplings together make the gear matrix singular (two joints driven as one): "
                              "reduce the coefficients")
        return C @ K

    # ------------------------------------------------------------------ state
    def reset(self, q_joint=None) -> None:
        """Put the arm at rest at ``q_joint`` (link angles, drive order; zeros by default), time 0.

        Elastic joints start deflected to their static equilibrium under gravity (as if the motors had held the
        arm there); thermal rise and transmitted load start from the config's initial values.
        """
        n, d = self.n, self.dyn
        q_joint = np.zeros(n) if q_joint is None else np.asarray(q_joint, dtype=float).reshape(n)
        q_pin = d.perm @ q_joint
        delta = np.zeros(d.ne)
        if d.ne:
            g = d.gravity_link(q_pin)
            for c, j in enumerate(self.elastic_joints):
                gj = float(d.perm[:, j] @ g)
                excess = -gj / self.spring_k[c]
                delta[c] = excess + math.copysign(self.spring_half[c], excess) if excess != 0 else 0.0
        self._z = d.z_from_link(q_pin, delta)
        self._zd = np.zeros(d.nz)
        self._t = 0.0
        self._sign = np.zeros(n)
        self._tau = np.zeros(n)
        self._tau_key = self._tau.tobytes()
        self._last_duration = None
        self._a = None                 # previous step's acceleration (extrapolates the mid-step velocity)
        self._stuck = None
        self._rest_pending = True      # some axis with dry friction may be at rest: run the stick check
        self._temperature_rise = self.friction.thermal_initial.copy()
        self._load = np.zeros(n)
        self._refresh_levels()

    def set_state(self, q_motor, dq_motor, delta=None, delta_dot=None) -> None:
        """Set motor angles/velocities (and deflections) directly; friction signs follow the velocities."""
        n, d = self.n, self.dyn
        self._z = np.concatenate([np.asarray(q_motor, dtype=float).reshape(n),
                                  np.zeros(d.ne) if delta is None else np.asarray(delta, dtype=float)])
        self._zd = np.concatenate([np.asarray(dq_motor, dtype=float).reshape(n),
                                   np.zeros(d.ne) if delta_dot is None else np.asarray(delta_dot, dtype=float)])
        self._sign = np.sign(self._zd[:n]) * self._active
        self._a = None
        self._stuck = None
        self._rest_pending = True
        self._refresh_levels()

    @property
    def t(self) -> float:
        return self._t

    @property
    def q_motor(self) -> np.ndarray:
        return self._z[: self.n].copy()

    @property
    def dq_motor(self) -> np.ndarray:
        return self._zd[: self.n].copy()

    @property
    def q_joint(self) -> np.ndarray:
        """Link angles (drive order); = ``K q_motor + joint_offset`` plus the deflection of elastic joints."""
        return self.dyn.perm.T @ self.dyn.q_link(self._z)

    @property
    def dq_joint(self) -> np.ndarray:
        return self.dyn.perm.T @ (self.dyn.J @ self._zd)

    @property
    def deflection(self) -> np.ndarray:
        """Deflections ``q_link - q_gear`` of the elastic joints (order of ``elastic_joints``), rad."""
        return self._z[self.n:].copy()

    @property
    def stuck(self) -> np.ndarray:
        """Axes held by stiction during the last step (bool, n)."""
        return np.zeros(self.n, dtype=bool) if self._stuck is None else self._stuck.copy()

    @property
    def temperature_rise(self) -> np.ndarray:
        """Winding temperature rise of ``thermal_drift`` axes, K."""
        return self._temperature_rise.copy()

    # ------------------------------------------------------------------ physics
    def inverse_dynamics(self, q_motor, dq_motor, ddq_motor) -> np.ndarray:
        """Eq. 1 with the true parameters, no friction: ``K^T (M q_dd + h q_d + g) + J_a theta_m_dd`` (N*m).

        Uses the true link model (including a ``payload_change``); elasticity and cogging are not part of eq. 1.
        """
        return self.dyn.inverse_dynamics(q_motor, dq_motor, ddq_motor)

    def gravity_torque(self, q_joint=None) -> np.ndarray:
        """Motor-side gravity torque ``K^T g(q)`` at link angles ``q_joint`` (default: the current ones)."""
        q_joint = self.q_joint if q_joint is None else np.asarray(q_joint, dtype=float)
        q_motor = self.dyn.z_from_link(self.dyn.perm @ q_joint)[: self.n]     # through the arm's (true) K
        z = np.zeros(self.n)
        return self.dyn.inverse_dynamics(q_motor, z, z)

    def forward_dynamics(self, q_motor, dq_motor, tau_motor) -> np.ndarray:
        """Motor accelerations of eq. 1 for sliding axes (friction sign from the velocities), rigid joints.

        The plant's own acceleration function, for checks: no state is changed.
        """
        saved = (self._z, self._zd, self._sign, self._a, self._stuck, self._rest_pending)
        try:
            self.set_state(q_motor, dq_motor)
            return self._accel(self._z, self._zd, np.asarray(tau_motor, dtype=float), None)[: self.n].copy()
        finally:
            self._z, self._zd, self._sign, self._a, self._stuck, self._rest_pending = saved
            self._refresh_levels()

    def energy(self) -> float:
        """Total mechanical energy: links + rotors kinetic, gravity potential, springs (J)."""
        return self.dyn.kinetic_energy(self._z, self._zd) + self.dyn.potential_energy(self._z) + self._spring_energy()

    def _spring_energy(self) -> float:
        if not self.dyn.ne:
            return 0.0
        delta = self._z[self.n:]
        excess = delta - np.clip(delta, -self.spring_half, self.spring_half)
        return float(0.5 * np.sum(self.spring_k * excess ** 2))

    def _max_spring_omega(self) -> float:
        """Highest natural frequency of the springs against the inertia at the zero pose (rad/s)."""
        d = self.dyn
        z = d.z_from_link(np.zeros(self.n))
        Mz = d.mass_matrix_z(d.q_link(z))
        Kz = np.zeros((d.nz, d.nz))
        Kz[self.n:, self.n:] = np.diag(self.spring_k)
        w2 = np.linalg.eigvals(np.linalg.solve(Mz, Kz)).real
        return float(np.sqrt(max(w2.max(), 1e-12)))

    def _refresh_levels(self):
        """Friction levels (f_c, f_s per axis, in each axis's current direction) for this step."""
        fr = self.friction
        scale = fr.scale(self._temperature_rise) if fr.has_thermal else None
        self._scale = scale
        self._fc, self._fs = fr.levels(self._sign, scale, self._load if fr.has_load else None)
        self._coulomb_signed = self._sign * self._fc
        self._tau_j = None             # K^-T (tau - f_c sgn), cached for the fast path
        # crossing check: sign * velocity <= 0 on sliding axes; +inf pads axes without a sign (stuck, frictionless)
        self._sign_pad = np.where(self._sign == 0.0, np.inf, 0.0)

    def _forces(self, z, zd, tau):
        """Generalized forces Q (nz): motor rows tau + cogging - friction (sliding law), spring rows."""
        n = self.n
        Q = np.empty(self.dyn.nz)
        f = self.friction.sliding(zd[:n], self._sign, self._fc, self._fs, self._scale)
        Q[:n] = tau - f
        if self.has_cogging:
            k = self.cog_axes
            Q[k] += self.cog_amp * np.sin(self.cog_periods * z[k] + self.cog_phase)
        if self.dyn.ne:
            delta, ddelta = z[n:], zd[n:]
            excess = delta - np.clip(delta, -self.spring_half, self.spring_half)
            contact = np.abs(delta) >= self.spring_half
            Q[n:] = -self.spring_k * excess - self.spring_d * ddelta * contact
        return Q

    def _accel(self, z, zd, tau, stuck):
        """z_dd at (z, zd) under motor torque ``tau`` with the current friction signs and stuck set.

        Sets ``self._lam`` (friction holding the stuck axes) and ``self._Qm`` (the forces used)."""
        d = self.dyn
        if stuck is None and self._simple:
            # eq. 1 as ABA with armature: (M + A) q_dd = K^-T (tau - f_c sgn) - K^-T B w - nle
            if self._tau_j is None:
                self._tau_j = d.Kp_inv_T @ (tau - self._coulomb_signed)
            return d.Kp_inv @ pin.aba(d.model_arm, d.data_arm, d.Kp @ z + d.off_p, d.Kp @ zd,
                                      self._tau_j - self._viscous_j @ zd)
        Q = self._forces(z, zd, tau)
        self._Qm = Q
        if d.fast:
            a, self._lam = d.solve_fast(z, zd, Q, stuck)
        else:
            a, self._lam = d.solve(z, zd, Q, stuck)
        return a

    def _stick_solve(self, z, zd, tau, candidates):
        """Decide which resting axes stay stuck; return (acceleration at (z, zd), stuck set or None).

        Solve with every candidate held (acceleration 0), which gives the friction ``lam`` each needs; release
        those whose need exceeds f_s in the direction of ``lam`` (they slide that way with Coulomb friction) and
        re-solve until consistent."""
        stuck = candidates.copy()
        fr = self.friction
        d = self.dyn
        n = self.n
        while True:
            if self._all_stuck_rigid and stuck.all():
                # whole arm held (every velocity is 0): the holding friction is what gravity and the motors
                # leave over, no dynamics solve needed
                Q = self._forces(z, zd, tau)
                self._Qm = Q
                lam = Q - d.Kp.T @ d.gravity_link(d.Kp @ z + d.off_p)
                a = np.zeros(n)
            else:
                a = self._accel(z, zd, tau, stuck)
                lam = self._lam
            direction = np.sign(lam)
            _, fs = fr.levels(direction, self._scale, self._load if fr.has_load else None)
            release = stuck & (np.abs(lam) > fs)
            if not release.any():
                break
            self._sign[release] = direction[release]
            stuck &= ~release
            self._refresh_levels()
            if not stuck.any():
                stuck = None
                a = self._accel(z, zd, tau, None)
                lam = np.zeros(n)
                break
        self._lam = lam
        return a, stuck

    def _substep_sliding(self, h, tau):
        """:meth:`_substep` specialised for the fast path with every axis sliding (the common case while moving):
        the same arithmetic, inlined (no constraint, no effects), to keep the per-sample cost low."""
        d = self.dyn
        z, zd, a_prev = self._z, self._zd, self._a
        hh = 0.5 * h
        z_mid = z + hh * zd
        zd_mid = zd if a_prev is None else zd + hh * a_prev
        tau_j = self._tau_j
        if tau_j is None:
            tau_j = self._tau_j = d.Kp_inv_T @ (tau - self._coulomb_signed)
        a = d.Kp_inv @ pin.aba(d.model_arm, d.data_arm, d.Kp @ z_mid + d.off_p, d.Kp @ zd_mid,
                               tau_j - self._viscous_j @ zd_mid)
        zd_new = zd + h * a
        z_new = z_mid + hh * zd_new
        self._stuck = None
        if self._any_active:
            sgn = self._sign
            if (sgn * zd_new + self._sign_pad).min() <= 0.0:
                crossed = (sgn * zd_new <= 0.0) & (sgn != 0.0)
                zd_new[crossed] = 0.0
                sgn[crossed] = 0.0
                self._rest_pending = True
                a = None
                self._refresh_levels()
        self._z, self._zd, self._a = z_new, zd_new, a

    def _substep(self, h, tau):
        """One fixed step of the midpoint (leapfrog) scheme with one dynamics evaluation::

            z_mid = z + h/2 v,   a = a(z_mid, v + h/2 a_prev),   v' = v + h a,   z' = z_mid + h/2 v'

        with the stick/slip decision taken at the midpoint (stuck axes: a = 0, so they stay exactly put)."""
        n = self.n
        z, zd = self._z, self._zd
        a_prev = self._a
        z_mid = z + (0.5 * h) * zd
        zd_mid = zd if a_prev is None else zd + (0.5 * h) * a_prev
        stuck = None
        if self._rest_pending:
            candidates = self._active & (zd[:n] == 0.0)
            if candidates.any():
                a, stuck = self._stick_solve(z_mid, zd_mid, tau, candidates)
            else:
                a = self._accel(z_mid, zd_mid, tau, None)
            self._rest_pending = stuck is not None
        else:
            a = self._accel(z_mid, zd_mid, tau, None)
        self._stuck = stuck
        if self.friction.has_load:
            Qm = self._Qm[:n] if stuck is None else self._Qm[:n] - self._lam
            self._load = Qm - self.dyn.motor_inertia * a[:n]
        if stuck is not None and self._all_stuck_rigid and stuck.all():
            self._a = a                      # zeros: held in place for this step, nothing moves
            if not self.friction.constant:
                self._refresh_levels()
            return
        zd_new = zd + h * a
        z_new = z_mid + (0.5 * h) * zd_new
        if self._any_active:
            sgn = self._sign
            if (sgn * zd_new[:n] + self._sign_pad).min() <= 0.0:
                # velocity would cross zero: the axis stops here and is a stuck candidate next step
                crossed = (sgn * zd_new[:n] <= 0.0) & (sgn != 0.0)
                zd_new[:n][crossed] = 0.0
                sgn[crossed] = 0.0
                self._rest_pending = True
                a = None
                self._refresh_levels()
            elif not self.friction.constant:
                self._refresh_levels()
        self._z, self._zd, self._a = z_new, zd_new, a

    def step(self, tau_motor, duration: float) -> None:
        """Apply motor-shaft torques ``tau_motor`` (N*m, drive order) held for ``duration`` s.

        Uses ``ceil(duration / h_max)`` equal fixed steps; deterministic (no randomness in the physics).
        """
        tau = np.asarray(tau_motor, dtype=float)
        if tau.shape != (self.n,):
            tau = tau.reshape(self.n)
        if duration <= 0:
            if duration < 0:
                raise ValueError(f"duration must be >= 0, got {duration}")
            return
        key = tau.tobytes()
        if key != self._tau_key:
            if not np.all(np.isfinite(tau)):
                raise ValueError(f"tau_motor must be finite, got {tau.tolist()}: a controller produced NaN/inf "
                                 "(check its gains and inputs); the plant was not stepped")
            self._tau_j = None
            self._tau = tau.copy()
            self._tau_key = key
        if duration != self._last_duration:
            self._last_steps = max(1, math.ceil(duration / self.h_max - 1e-9))
            self._last_duration = duration
        steps = self._last_steps
        h = duration / steps
        fr = self.friction
        if fr.has_thermal:
            self._refresh_levels()
        simple = self._simple
        # a torque_offset is a constant load on the rotor: the links see the drive's torque less it (the drive's
        # current, what the sensors report, is still tau)
        tau_net = tau - self.load_offset if self.has_load_offset else tau
        for _ in range(steps):
            if simple and not self._rest_pending:
                self._substep_sliding(h, tau_net)
            else:
                self._substep(h, tau_net)
        self._t += duration
        if fr.has_thermal:
            # first-order temperature, exact for the held current and friction power:
            # dT' = (heating I^2 + friction_power_heating |f w| - dT) / tau_th, f w at the step's end
            current = tau / self.sensors.torque_constant
            velocity = self._zd[: self.n]
            friction = fr.sliding(velocity, self._sign, self._fc, self._fs, self._scale)
            target = fr.heat_target(current, friction, velocity)
            decay = np.exp(-duration / fr.thermal_time_constant)
            self._temperature_rise = target + (self._temperature_rise - target) * decay
            self._refresh_levels()

    def read_sensors(self) -> SensorReading:
        """What the drives report now: encoder counts/position (quantised), current (noisy, quantised), kt*I."""
        return self.sensors.read(self._z[: self.n], self._tau, self._t)
