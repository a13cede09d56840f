"""Random test cases: rate, duration, host controller, trajectory and 0-2 concealed effects (js2spec effect names)."""
from __future__ import annotations

import numpy as np
import pinocchio as pin

from .arm import NJ, Q_CENTER, TrueArm
from .trajectory import build_trajectory, draw_trajectory

RATES = (100, 200, 250, 500, 1000)
KINDS = ("stribeck", "cogging", "payload_change", "thermal_drift", "load_dependent_friction",
         "asymmetric_friction", "joint_elasticity", "backlash", "torque_offset", "coupling")


def link_inertia_about_axis(arm: TrueArm, j: int, q=None) -> float:
    """Inertia of everything beyond joint j about its axis (the locked-rotor link inertia), at the mid pose."""
    q = Q_CENTER.copy() if q is None else q
    M = pin.crba(arm.model, arm.data, q)
    return float(M[j, j])


def _controller(rng, rate):
    if rng.random() < 0.5:
        bw = float(rng.uniform(5.0, min(15.0, rate / 12.0)))
        return dict(type="computed_torque", bandwidth_hz=bw, damping_ratio=float(rng.uniform(0.7, 1.0)),
                    velocity_filter_hz=float(min(150.0, rate / 3.0)))
    vbw = float(min(50.0, rate / 10.0) * rng.uniform(0.7, 1.0))
    return dict(type="cascade", velocity_bandwidth_hz=vbw, position_bandwidth_hz=float(vbw / rng.uniform(3.0, 5.0)),
                integral_corner_hz=float(vbw / rng.uniform(4.0, 8.0)), velocity_filter_hz=float(min(150.0, rate / 3.0)))


def _effect(kind, j, rng, arm: TrueArm, others):
    fc = float(arm.fc[j])
    frac = float(rng.uniform(0.3, 1.5))
    e = {"kind": kind, "joints": [int(j)]}
    if kind == "stribeck":
        e.update(velocity=float(rng.uniform(0.5, 5.0)), shape=float(rng.uniform(0.5, 2.5)), static=fc * (1 + frac))
    elif kind == "cogging":
        e.update(amplitude=fc * float(rng.uniform(0.3, 1.0)), periods_per_rev=float(rng.choice([6, 12, 18, 24, 36])),
                 phase=float(rng.uniform(-np.pi, np.pi)))
    elif kind == "payload_change":
        d = rng.normal(size=3)
        d *= rng.uniform(0, 0.08) / np.linalg.norm(d)
        e.update(mass=float(rng.uniform(0.3, 3.0)), com=d.tolist(), inertia=[0.0, 0.0, 0.0])
    elif kind == "thermal_drift":
        ratio = float(rng.uniform(1.3, 2.0))
        e.update(time_constant=float(rng.uniform(10, 120)), friction_per_kelvin=0.004, initial_rise=0.0)
        if rng.random() < 0.5:      # copper losses (tau_m^2 as the current proxy) or friction power; sized later
            e.update(heating=1.0, friction_power_heating=0.0)
        else:
            e.update(heating=0.0, friction_power_heating=1.0)
        e["_target_scale"] = ratio
    elif kind == "load_dependent_friction":
        load = 0.5 * float(arm.gravity_scale[j] + 0.4 * arm.inertial_scale[j])
        e.update(coefficient=float(np.clip(frac * fc / max(load, 1e-6), 0.02, 1.0)))
    elif kind == "asymmetric_friction":
        e.update(negative_scale=float(rng.uniform(0.4, 0.7) if rng.random() < 0.5 else rng.uniform(1.4, 2.5)))
    elif kind == "joint_elasticity":
        J = link_inertia_about_axis(arm, j)
        w = 2 * np.pi * rng.uniform(10, 40)
        zeta = rng.uniform(0.02, 0.1)
        e.update(stiffness=float(J * w ** 2), damping=float(2 * zeta * J * w))
    elif kind == "backlash":
        e.update(width=float(rng.uniform(0.002, 0.012)))
        if "joint_elasticity" not in [o["kind"] for o in others if o["joints"][0] == j]:
            J = link_inertia_about_axis(arm, j)
            w = 2 * np.pi * rng.uniform(40, 80)
            e.update(stiffness=float(J * w ** 2), damping=float(2 * 0.05 * J * w))
    elif kind == "torque_offset":
        e.update(offset=float(fc * rng.uniform(0.2, 1.0) * rng.choice([-1, 1])))
    elif kind == "coupling":
        i = int(rng.choice([k for k in range(NJ) if k != j]))
        e.update(from_joint=i, coefficient=float(rng.uniform(0.02, 0.1) * rng.choice([-1, 1])))
    return e


def _calibrate_thermal(effects, trajectory, duration, arm: TrueArm):
    """Size thermal_drift's heating so the friction scale ends near the drawn target: the nominal motor torque and
    friction power along the desired trajectory are run through the first-order temperature model."""
    notes = []
    for e in effects:
        if e["kind"] != "thermal_drift":
            continue
        j = e["joints"][0]
        target = e.pop("_target_scale")
        t = np.arange(0.0, duration, 0.01)
        q, qd, qdd = build_trajectory(trajectory, t)
        w = qd @ arm.Kinv.T
        fr = arm.B * w + arm.fc * np.tanh(w / 0.05)
        tau = np.array([arm.K.T @ pin.rnea(arm.model, arm.data, a, b, c) for a, b, c in zip(q, qd, qdd)]) \
            + arm.Ja * (qdd @ arm.Kinv.T) + fr
        src = tau[:, j] ** 2 if e["heating"] > 0 else np.abs(fr[:, j] * w[:, j])
        a, alpha = 0.01 / e["time_constant"], e["friction_per_kelvin"]
        fb = e["heating"] == 0              # friction power grows with the heated friction: include that feedback

        def final_scale(gain):
            dT = 0.0
            for x in src:
                dT += a * (gain * x * ((1 + alpha * dT) if fb else 1.0) - dT)
            return 1 + alpha * dT

        lo, hi = 0.0, 1.0
        while final_scale(hi) < target and hi < 1e12:
            hi *= 10
        for _ in range(40):                 # bisection on the gain
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if final_scale(mid) < target else (lo, mid)
        key = "heating" if e["heating"] > 0 else "friction_power_heating"
        e[key] = float(0.5 * (lo + hi))
        notes.append(dict(kind="thermal_drift", joint=j, target_final_friction_scale=target,
                          note="sized on the nominal torque along the desired trajectory; the achieved value is "
                               "truth.json thermal_final_friction_scale"))
    return notes


def draw_case(seed: int, arm_seed: int = 0) -> dict:
    rng = np.random.default_rng(np.random.SeedSequence([0xCA5E, int(seed)]))
    arm = TrueArm(arm_seed)
    rate = int(rng.choice(RATES))
    duration = float(round(rng.uniform(30, 60), 1))
    u = rng.random()
    n_eff = 0 if u < 0.15 else (1 if u < 0.6 else 2)
    kinds = list(rng.choice(KINDS, size=n_eff, replace=False))
    effects = []
    used = []
    for kind in kinds:
        allowed = list(range(NJ))
        if kind == "payload_change":
            allowed = [2, 3, 4, 5]
        if kind in ("joint_elasticity", "backlash"):
            allowed = [0, 1, 2, 3, 4]          # link 6 has ~no inertia about its axis: no two-mass mode there
        allowed = [j for j in allowed if j not in used] or allowed
        j = int(rng.choice(allowed))
        used.append(j)
        effects.append(_effect(str(kind), j, rng, arm, effects))
    controller = _controller(rng, rate)
    trajectory = draw_trajectory(rng, duration)
    notes = _calibrate_thermal(effects, trajectory, duration, arm)
    return dict(seed=int(seed), arm_seed=int(arm_seed), rate_hz=rate, duration_s=duration,
                controller=controller, trajectory=trajectory, effects=effects, effect_notes=notes,
                sensor=dict(encoder_counts_per_rev=65536, torque_noise_rel_rms=0.005, torque_quantum=1e-4),
                noise_seed=int(rng.integers(2 ** 31)))
