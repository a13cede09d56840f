"""The plant: motors with Karnopp stiction, a transmission K_true, rigid or elastic (backlash) joints, pinocchio links.

Generalised coordinates z = (theta_m [6 motor angles], q_E [link angles of the elastic joints E]). Link angles
q = A theta + S q_E + offset (offset rows of E zeroed: q_E are link angles), with A = K_true whose rows in E are zeroed and S selecting E; the gear output of an
elastic joint e is g_e = K_true[e] theta + offset[e]. Kinetic energy 1/2 qd^T M(q) qd + 1/2 w^T diag(J_a) w gives the
mass matrix T^T M T + blkdiag(J_a, 0) (T = [A S]); link bias forces (Coriolis, gravity) enter as -T^T rnea(q, qd, 0).
A spring-damper (with an optional dead zone: backlash) of torque tau_s = k dz(g_e - q_e) + d (gd_e - qd_e) acts on
the link (+tau_s) and back on the motors (-K_true[e]^T tau_s). Integration: semi-implicit Euler at a fixed step.
"""
from __future__ import annotations

import numpy as np
import pinocchio as pin

from .arm import NJ, TrueArm


def dead_zone(x, half_width):
    """Backlash dead zone: 0 inside |x| < half_width, x -/+ half_width outside."""
    return np.sign(x) * np.maximum(np.abs(x) - half_width, 0.0)


def spring_torque(defl, defl_rate, k, d, half_width):
    """Torque of the joint spring (on the link) for deflection gear - link; no torque inside the dead zone."""
    contact = np.abs(defl) > half_width
    return np.where(contact, k * dead_zone(defl, half_width) + d * defl_rate, 0.0)


class Plant:
    """State (z, zd), motor torque input; ``effects`` the case's effect list (config form)."""

    def __init__(self, arm: TrueArm, effects=(), friction=True, gravity=True):
        self.arm = arm
        self.model = arm.model.copy()
        if not gravity:
            self.model.gravity.linear = np.zeros(3)
        self.friction_on = friction
        self.effects = [dict(e) for e in effects]
        self.Ktrue = arm.K.copy()
        self.offset = arm.offset.copy()
        self.B, self.fc, self.fs, self.Ja = arm.B.copy(), arm.fc.copy(), arm.fs.copy(), arm.Ja.copy()
        self.neg_scale = np.ones(NJ)
        self.stribeck = None               # (mask, v_s, shape, static)
        self.cog = None                    # (joint, A, p, phi)
        self.tau_const = np.zeros(NJ)      # torque_offset: load torque on rotors
        self.mu = np.zeros(NJ)
        self.thermal = None
        elastic = {}
        for e in self.effects:
            kind, j = e["kind"], int(e["joints"][0])
            if kind == "payload_change":
                jid = j + 1
                add = pin.Inertia(float(e["mass"]), np.asarray(e.get("com", [0, 0, 0]), float),
                                  np.diag(np.asarray(e.get("inertia", [0, 0, 0]), float)))
                self.model.inertias[jid] = self.model.inertias[jid] + add
            elif kind == "coupling":
                i = int(e["from_joint"])
                E = np.eye(NJ)
                E[j, i] += float(e["coefficient"])
                self.Ktrue = E @ self.Ktrue
            elif kind == "stribeck":
                self.stribeck = (j, float(e["velocity"]), float(e.get("shape", 2.0)), float(e["static"]))
                self.fs[j] = float(e["static"])
            elif kind == "cogging":
                self.cog = (j, float(e["amplitude"]), float(e["periods_per_rev"]), float(e.get("phase", 0.0)))
            elif kind == "torque_offset":
                self.tau_const[j] += float(e["offset"])
            elif kind == "load_dependent_friction":
                self.mu[j] = float(e["coefficient"])
            elif kind == "asymmetric_friction":
                self.neg_scale[j] = float(e["negative_scale"])
            elif kind == "thermal_drift":
                self.thermal = dict(j=j, heating=float(e.get("heating", 0.0)), tc=float(e["time_constant"]),
                                    alpha=float(e["friction_per_kelvin"]), dT=float(e.get("initial_rise", 0.0)),
                                    fph=float(e.get("friction_power_heating", 0.0)))
            elif kind == "joint_elasticity":
                elastic.setdefault(j, {}).update(k=float(e["stiffness"]), d=float(e.get("damping", 0.0)))
            elif kind == "backlash":
                el = elastic.setdefault(j, {})
                el["b"] = float(e["width"])
                if e.get("stiffness") is not None:
                    el.setdefault("k", float(e["stiffness"]))
                if e.get("damping") is not None:
                    el.setdefault("d", float(e["damping"]))
            else:
                raise ValueError(f"unknown effect kind {kind!r}")
        self.data = self.model.createData()
        self.E = np.array(sorted(elastic), int)
        self.nE = len(self.E)
        self.k_s = np.array([elastic[j]["k"] for j in self.E], float)
        self.d_s = np.array([elastic[j].get("d", 0.0) for j in self.E], float)
        self.hw = np.array([0.5 * elastic[j].get("b", 0.0) for j in self.E], float)
        self.n = NJ + self.nE
        A = self.Ktrue.copy()
        A[self.E, :] = 0.0
        S = np.zeros((NJ, self.nE))
        S[self.E, np.arange(self.nE)] = 1.0
        self.T = np.hstack([A, S])
        self.KE = self.Ktrue[self.E, :]
        self.offset_z = self.offset.copy()       # the link coordinates q_E are link angles already: no offset
        self.offset_z[self.E] = 0.0
        self.Jz = np.zeros(self.n)
        self.Jz[:NJ] = self.Ja
        self.dv = 0.02                      # Karnopp velocity band, rad/s motor side
        self.z = np.zeros(self.n)
        self.zd = np.zeros(self.n)
        self.tau_load = np.zeros(NJ)
        self.last_friction = np.zeros(NJ)
        self.last_effect_torque = np.zeros(NJ)    # friction-law/cogging/offset effects' own torque (motor side)
        self.stuck = np.zeros(NJ, bool)
        self.mass_every = 1                 # recompute the mass matrix every n steps (fine steps of elastic cases)
        self._count = 0
        self._Mz = None
        self._zeros = np.zeros(NJ)
        self._il = np.tril_indices(NJ, -1)
        self._diag = np.diag_indices(self.n)

    # ---- kinematics of the state
    def link_state(self, z=None, zd=None):
        z = self.z if z is None else z
        zd = self.zd if zd is None else zd
        return self.T @ z + self.offset_z, self.T @ zd

    def set_rest(self, q0):
        """At rest with links at q0 (elastic joints pre-deflected by the static gravity load)."""
        q0 = np.asarray(q0, float)
        g = q0.copy()
        if self.nE:
            tg = pin.computeGeneralizedGravity(self.model, self.data, q0)[self.E]
            g[self.E] = q0[self.E] + tg / self.k_s + np.sign(tg) * self.hw
        self.z = np.concatenate([np.linalg.solve(self.Ktrue, g - self.offset), q0[self.E]])
        self.zd = np.zeros(self.n)

    # ---- friction law (motor side); returns sliding friction and the breakaway level
    def _friction_levels(self, w):
        fc = self.fc + self.mu * np.abs(self.tau_load)
        fs = self.fs + self.mu * np.abs(self.tau_load)
        B = self.B
        if self.thermal is not None:
            s = np.ones(NJ)
            s[self.thermal["j"]] = max(0.0, 1.0 + self.thermal["alpha"] * self.thermal["dT"])
            fc, fs, B = fc * s, fs * s, B * s
        return fc, fs, B

    def _sliding(self, w, fc, fs, B, direction):
        mag = fc.copy()
        if self.stribeck is not None:
            j, vs, sh, _ = self.stribeck
            mag[j] = fc[j] + (fs[j] - fc[j]) * np.exp(-(abs(w[j]) / vs) ** sh)
        # asymmetric_friction (js2spec): f_c, f_s and the Stribeck hump scaled in the negative direction, not B
        mag = np.where(direction < 0, mag * self.neg_scale, mag)
        return B * w + direction * mag

    def _baseline_friction(self, w, direction):
        return self.B * w + direction * self.fc

    def mass_matrix(self, q):
        M = pin.crba(self.model, self.data, q)
        M[self._il] = M.T[self._il]               # crba fills the upper triangle
        Mz = self.T.T @ M @ self.T
        Mz[self._diag] += self.Jz
        return Mz

    # ---- one step
    def accelerations(self, tau_m, t=0.0):
        """Generalised accelerations (and sets the stuck set, friction) for the current state and motor torque."""
        q, qd = self.link_state()
        if self._count % self.mass_every == 0 or self._Mz is None:
            self._Mz = self.mass_matrix(q)
        self._count += 1
        Mz = self._Mz
        h = pin.rnea(self.model, self.data, q, qd, self._zeros)
        T = self.T
        F = -(T.T @ h)
        w = self.zd[:NJ]
        theta = self.z[:NJ]
        ext = -self.tau_const.copy()              # load torques acting on the rotors
        if self.cog is not None:
            j, A, p, phi = self.cog
            ext[j] -= A * np.sin(p * theta[j] + phi)
        F[:NJ] += tau_m + ext
        if self.nE:
            gE = self.KE @ theta + self.offset[self.E]
            gdE = self.KE @ w
            ts = spring_torque(gE - self.z[NJ:], gdE - self.zd[NJ:], self.k_s, self.d_s, self.hw)
            F[:NJ] -= self.KE.T @ ts
            F[NJ:] += ts
        f = np.zeros(NJ)
        stuck = np.zeros(NJ, bool)
        if self.friction_on:
            fc, fs, B = self._friction_levels(w)
            inband = np.abs(w) < self.dv
            direction = np.sign(w)
            slide = ~inband
            f[slide] = self._sliding(w, fc, fs, B, direction)[slide]
            stuck = inband.copy()
            fz = np.zeros(self.n)
            for _ in range(NJ + 1):           # Karnopp: release stuck axes whose holding torque exceeds f_s
                fz[:NJ] = f
                if not stuck.any():
                    a = np.linalg.solve(Mz, F - fz)
                    break
                free = ~np.concatenate([stuck, np.zeros(self.nE, bool)])
                a = np.zeros(self.n)
                if free.any():
                    a[free] = np.linalg.solve(Mz[np.ix_(free, free)], (F - fz)[free])
                need = F[:NJ] - Mz[:NJ] @ a          # friction needed to hold the stuck axes
                fs_dir = np.where(need < 0, fs * self.neg_scale, fs)
                release = stuck & (np.abs(need) > fs_dir)
                if not release.any():
                    f[stuck] = need[stuck]
                    break
                stuck &= ~release
                f[release] = self._sliding(w * 0.0, fc, fs, B, np.sign(need))[release]
            base = self._baseline_friction(w, np.where(stuck, 0.0, np.sign(np.where(inband, f, w))))
            self.last_effect_torque = np.where(stuck, 0.0, f - base)
        else:
            a = np.linalg.solve(Mz, F)
            self.last_effect_torque = np.zeros(NJ)
        # rotor loads (cogging, offset) of a stuck axis are held by its static friction: not visible in the torque
        self.last_effect_torque = np.where(stuck, 0.0, self.last_effect_torque - ext)
        self.stuck = stuck
        self.last_friction = f
        self.tau_load = tau_m + ext - f - self.Ja * a[:NJ]
        return a, f

    def step(self, tau_m, dt, t=0.0):
        a, f = self.accelerations(tau_m, t)
        self.zd = self.zd + dt * a
        self.zd[:NJ][self.stuck] = 0.0
        self.z = self.z + dt * self.zd
        if self.thermal is not None:
            th = self.thermal
            j = th["j"]
            P = abs(f[j] * self.zd[j])
            th["dT"] += dt * (th["heating"] * tau_m[j] ** 2 + th["fph"] * P - th["dT"]) / th["tc"]

    # ---- energy (for tests): kinetic + potential + spring
    def energy(self):
        q, qd = self.link_state()
        Mz = self.mass_matrix(q)
        kin = 0.5 * self.zd @ Mz @ self.zd
        pot = pin.computePotentialEnergy(self.model, self.data, q)
        if self.nE:
            d = self.KE @ self.z[:NJ] + self.offset[self.E] - self.z[NJ:]
            pot += 0.5 * np.sum(self.k_s * dead_zone(d, self.hw) ** 2)
        return kin + pot
