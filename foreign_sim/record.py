"""Simulate a case and write recording.npz, truth.json and drives.yaml."""
from __future__ import annotations

import json
import shutil
import sys
import time
from pathlib import Path

import numpy as np
import pinocchio as pin

from .arm import DRIVES, NJ, Q_CENTER, URDF, TrueArm
from .plant import Plant
from .trajectory import build_trajectory

ENC_Q = 2 * np.pi / 65536


class HostController:
    """Runs at the recording rate on the encoder readings; returns the (saturated) motor torque."""

    def __init__(self, arm: TrueArm, cfg: dict, rate: float):
        self.arm, self.cfg, self.rate = arm, cfg, rate
        self.m, self.d = arm.nom_model, arm.nom_model.createData()
        self.K, self.Kinv, self.off = arm.K, arm.Kinv, arm.offset
        self.nom = arm.nom
        self.alpha = 1.0 - np.exp(-2 * np.pi * cfg["velocity_filter_hz"] / rate)
        self.prev = None
        self.w_f = np.zeros(NJ)
        self.integ = np.zeros(NJ)
        if cfg["type"] == "cascade":
            Mm = self.K.T @ pin.crba(self.m, self.d, Q_CENTER.copy()) @ self.K
            Jd = np.diag(0.5 * (Mm + Mm.T)) + self.nom["Ja"]
            wv = 2 * np.pi * cfg["velocity_bandwidth_hz"]
            self.Kv = Jd * wv
            self.Ki = self.Kv * 2 * np.pi * cfg["integral_corner_hz"]
            self.Kp = 2 * np.pi * cfg["position_bandwidth_hz"]
        else:
            w = 2 * np.pi * cfg["bandwidth_hz"]
            self.Kp, self.Kd = w * w, 2 * cfg["damping_ratio"] * w

    def __call__(self, theta_enc, qd_des, q_des, qdd_des):
        if self.prev is None:
            self.prev = theta_enc.copy()
        w_raw = (theta_enc - self.prev) * self.rate
        self.prev = theta_enc.copy()
        self.w_f += self.alpha * (w_raw - self.w_f)
        q = self.K @ theta_enc + self.off
        if self.cfg["type"] == "computed_torque":
            qd = self.K @ self.w_f
            a = qdd_des + self.Kp * (q_des - q) + self.Kd * (qd_des - qd)
            tj = pin.rnea(self.m, self.d, q, qd, a)
            tau = self.K.T @ tj + self.nom["Ja"] * (self.Kinv @ a) + self.nom["B"] * self.w_f \
                + self.nom["fc"] * np.tanh(self.w_f / 0.2)
        else:
            th_d = self.Kinv @ (q_des - self.off)
            w_ref = self.Kinv @ qd_des + self.Kp * (th_d - theta_enc)
            ev = w_ref - self.w_f
            self.integ += ev / self.rate
            tau = self.Kv * ev + self.Ki * self.integ \
                + self.K.T @ pin.computeGeneralizedGravity(self.m, self.d, q)
        sat = self.arm.tau_sat
        tau_s = np.clip(tau, -sat, sat)
        if self.cfg["type"] == "cascade":      # anti-windup: undo the integration while saturated
            self.integ -= np.where(tau_s != tau, ev / self.rate, 0.0)
        return tau_s


def internal_rate(case) -> int:
    kinds = {e["kind"] for e in case["effects"]}
    return 10000 if kinds & {"joint_elasticity", "backlash"} else 2000


def simulate(case: dict, arm: TrueArm | None = None, progress=True):
    """Returns dict of arrays: times, theta (true motor angles), tau_cmd, q (true link angles), effect torques."""
    arm = arm or TrueArm(case.get("arm_seed", 0))
    rate = int(case["rate_hz"])
    fsim = internal_rate(case)
    nsub = fsim // rate
    dt = 1.0 / fsim
    N = int(round(case["duration_s"] * rate))
    t = np.arange(N) / rate
    q_des, qd_des, qdd_des = build_trajectory(case["trajectory"], t)
    plant = Plant(arm, case["effects"])
    plant.mass_every = max(1, fsim // 2000)     # mass matrix at >= 2 kHz, bias forces and springs every step
    plant.set_rest(q_des[0])
    ctrl = HostController(arm, case["controller"], rate)
    theta = np.zeros((N, NJ))
    tau = np.zeros((N, NJ))
    qlink = np.zeros((N, NJ))
    qdlink = np.zeros((N, NJ))
    eff = np.zeros((N, NJ))
    defl = np.zeros((N, max(plant.nE, 1)))
    t0 = time.process_time()
    for k in range(N):
        th = plant.z[:NJ].copy()
        theta[k] = th
        qlink[k], qdlink[k] = plant.link_state()
        if plant.nE:
            defl[k] = plant.KE @ th + plant.offset[plant.E] - plant.z[NJ:]
        enc = np.floor(th / ENC_Q) * ENC_Q
        u = ctrl(enc, qd_des[k], q_des[k], qdd_des[k])
        tau[k] = u
        acc = np.zeros(NJ)
        for _ in range(nsub):
            plant.step(u, dt)
            acc += plant.last_effect_torque
        eff[k] = acc / nsub
        if progress and k % max(1, N // 10) == 0 and k:
            print(f"  t={t[k]:.1f}/{t[-1]:.1f} s  cpu {time.process_time() - t0:.1f} s", file=sys.stderr)
    cpu = time.process_time() - t0
    return dict(times=t, theta=theta, tau_cmd=tau, q=qlink, qd=qdlink, effect_torque=eff, deflection=defl,
                q_des=q_des, cpu_s=cpu, plant=plant, internal_rate_hz=fsim)


def _visibility(case, arm, sim):
    """Per effect: RMS of its own motor-side torque contribution on its motor vs RMS of that motor's torque."""
    tau = sim["tau_cmd"]
    rms_tau = np.sqrt(np.mean(tau ** 2, axis=0))
    out = []
    q, qd = sim["q"], sim["qd"]
    rate = case["rate_hz"]
    qdd = np.gradient(qd, 1.0 / rate, axis=0)
    for e in case["effects"]:
        j = e["joints"][0]
        kind = e["kind"]
        v = dict(kind=kind, joint=j)
        contrib = None
        if kind in ("stribeck", "cogging", "thermal_drift", "load_dependent_friction", "asymmetric_friction",
                    "torque_offset"):
            contrib = sim["effect_torque"][:, j]     # (all friction-law/rotor effects of this motor together)
        elif kind == "payload_change":
            m0, m1 = arm.model, sim["plant"].model
            d0, d1 = m0.createData(), m1.createData()
            diff = np.array([arm.K.T @ (pin.rnea(m1, d1, a, b, c) - pin.rnea(m0, d0, a, b, c))
                             for a, b, c in zip(q, qd, qdd)])
            contrib = diff[:, j]
            v["all_motors_rms"] = np.sqrt(np.mean(diff ** 2, axis=0)).tolist()
        elif kind == "coupling":
            m0, d0 = arm.model, arm.model.createData()
            Kt = sim["plant"].Ktrue
            tl = np.array([pin.rnea(m0, d0, a, b, c) for a, b, c in zip(q, qd, qdd)])
            diff = tl @ (Kt - arm.K)
            i = int(e["from_joint"])
            contrib = diff[:, i]
            v["motor"] = i
        elif kind in ("joint_elasticity", "backlash"):
            pl = sim["plant"]
            col = int(np.where(pl.E == j)[0][0])
            dfl = sim["deflection"][:, col]
            v["deflection_rms_rad"] = float(np.sqrt(np.mean(dfl ** 2)))
            v["note"] = "not separable as a torque; deflection (gear output - link, joint side) given instead"
        m = v.get("motor", j)
        if contrib is not None:
            v["effect_rms"] = float(np.sqrt(np.mean(contrib ** 2)))
            v["motor_torque_rms"] = float(rms_tau[m])
            v["ratio"] = float(v["effect_rms"] / max(rms_tau[m], 1e-12))
        out.append(v)
    return out


def _write(out_dir: Path, case: dict, arm: TrueArm, sim, wall):
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(case.get("noise_seed", 0))
    theta = sim["theta"]
    pos = np.floor(theta / ENC_Q) * ENC_Q
    tau = sim["tau_cmd"]
    rms = np.sqrt(np.mean(tau ** 2, axis=0))
    meas = tau + rng.normal(size=tau.shape) * 0.005 * rms
    meas = np.round(meas / 1e-4) * 1e-4
    np.savez(out_dir / "recording.npz", times=sim["times"], positions=pos, torques=meas)
    shutil.copy(DRIVES, out_dir / "drives.yaml")
    pl = sim["plant"]
    truth = dict(case=case, arm_seed=arm.arm_seed, arm=arm.truth_dict(),
                 nominal_urdf=str(URDF), drives="drives.yaml",
                 true_gear_ratio_matrix=pl.Ktrue.tolist(),
                 true_inertials_with_effects=arm.inertials(pl.model),
                 effects=case["effects"], visibility=_visibility(case, arm, sim),
                 units=dict(times="s", positions="rad, motor side (encoder, 2^16 counts/rev)",
                            torques="N*m, motor side (commanded saturated torque + noise)"),
                 conventions=dict(cogging="the drive supplies +A sin(p theta_m + phi) (a load on the rotor)",
                                  torque_offset="the drive supplies +offset (a load on the rotor)"),
                 internal_rate_hz=sim["internal_rate_hz"], cpu_s=sim["cpu_s"], wall_s=wall,
                 saturated_fraction=float(np.mean(np.abs(tau) >= arm.tau_sat * (1 - 1e-12))),
                 tracking_rms_rad=np.sqrt(np.mean((sim["q"] - sim["q_des"]) ** 2, axis=0)).tolist())
    if pl.thermal is not None:
        truth["thermal_final_friction_scale"] = 1.0 + pl.thermal["alpha"] * pl.thermal["dT"]
    (out_dir / "truth.json").write_text(json.dumps(truth, indent=1))
    return out_dir / "recording.npz"


def record_case(case: dict, out_dir: Path, arm_seed=0, progress=True) -> Path:
    w0 = time.time()
    arm = TrueArm(arm_seed)
    case = dict(case, arm_seed=int(arm_seed))
    sim = simulate(case, arm, progress=progress)
    return _write(out_dir, case, arm, sim, time.time() - w0)


def identification_recording(out_dir, arm_seed=0, rate_hz=500, duration_s=90, seed=12345, progress=True) -> Path:
    """A clean recording (no effects) with a rich excitation: multi-sines, moves with dwells and sweeps."""
    from .cases import _controller
    from .trajectory import draw_trajectory
    rng = np.random.default_rng(np.random.SeedSequence([0x1D, int(seed)]))
    case = dict(seed=int(seed), arm_seed=int(arm_seed), rate_hz=int(rate_hz), duration_s=float(duration_s),
                controller=_controller(rng, rate_hz), trajectory=draw_trajectory(rng, duration_s, pattern=["sines", "ptp", "sines", "sweep"]), effects=[],
                sensor=dict(encoder_counts_per_rev=65536, torque_noise_rel_rms=0.005, torque_quantum=1e-4),
                noise_seed=int(rng.integers(2 ** 31)), purpose="identification (clean)")
    return record_case(case, Path(out_dir), arm_seed=arm_seed, progress=progress)
