"""Replay a recording through the simulator: the identified model as a ``Plant``, driven along the recorded motion.

Inverse-dynamics replay (the mode that works on any recording, real ones included): the recorded motor angles,
velocities and accelerations (filtered as identification filters them) prescribe the motors' motion; the simulator
computes, sample by sample, the motor torque its physics needs to move that way (eq. 1 with the plant's own effect
implementations)::

    tau_m = K^T (M(q) q_dd + h(q, q_d) q_d + g(q)) + J_a theta_m_dd + f(theta_m_d; effects) - cogging(theta_m)

with ``M, h, g`` of the identified URDF (plus a ``payload_change``), ``B, f_c, f_s`` of ``model.yaml`` folded
through :class:`hil_sim.friction.Friction` (Stribeck, asymmetry, load-dependent friction with the transmitted load
``K^T (M q_dd + h + g)``, thermal drift with the winding temperature integrated from the simulated current as in
:meth:`hil_sim.plant.Plant.step`) and the cogging of :class:`hil_sim.plant.Plant`. Elastic joints
(``joint_elasticity``, ``backlash``): the motors' motion is prescribed, the deflections are simulated (the plant's
generalized coordinates ``z = [theta_m, delta]``, its mass matrix ``M_z`` and spring law), and the motor rows give
the torque::

    M_ee delta_dd = Q_spring - (J^T nle)_e - M_em theta_m_dd
    tau_m - f + cog = M_mm theta_m_dd + M_me delta_dd + (J^T nle)_m

Forward replay (:func:`forward_replay`): the plant integrated by :meth:`Plant.step` under the recorded torque plus
a tracking term ``M_z(theta) (w^2 e + 2 w e_dot)`` that keeps it near the recording; the joint-angle gap and the
tracking torque measure how far the model is from the arm.

The model's torque offsets (``off_<k>``, ``js2-identify --offsets``) are added on the recording's torque side (a
sensor zero, not physics). Joint-side recordings (torque sensors, ``torque_side: joint``) are compared on the joint
side, ``tau_j = K^-T tau_m``; their model's friction and ``J_a`` were identified on the joint side and are carried to
the motors through a diagonal K (``B_m = K_jj^2 B_j``, ``f_m = |K_jj| f_j``, ``J_a,m = K_jj^2 J_a,j``).

The recording's motion is taken exactly as identification takes it (``identification.signals.from_log``, the
model's filter cut-offs kept at or below 0.4 x the sample rate) — the one place ``hil_sim`` reads a recording.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pinocchio as pin

from js2spec.drives import at_rest, motor_rest_speed
from js2spec.errors import ConfigError, Js2Error
from js2spec.model import friction_hold_limit

from .effects import parse_effects
from .plant import Plant
from .truth import SimTruth


class ReplayError(Js2Error):
    """The recording cannot be replayed through the model (another arm, unsupported transmission)."""


@dataclass(frozen=True)
class _ModelArm:
    """What :class:`Plant` needs of a robot, built from an identified model and a recording's drives."""
    name: str
    urdf_text: str
    urdf_path: Path | None
    drives: object


def model_motor_side(model, drives) -> dict:
    """The model's ``J_a``, ``B``, ``f_c``, ``f_s`` on the motor side (see the module docstring for joint-side
    models); ``f_s`` defaults to ``f_c`` where the model has none (the simultaneous method)."""
    K = np.asarray(drives.gear_ratio_matrix, float)
    ja, b, fc = model.motor_inertia.copy(), model.friction_viscous.copy(), model.friction_coulomb.copy()
    fs = np.where(np.isfinite(model.friction_static), model.friction_static, fc)
    if str(drives.torque_side) == "joint" and not np.allclose(K, np.eye(len(K))):
        if np.any(np.abs(K - np.diag(np.diag(K))) > 1e-12):
            raise ReplayError(f"{model.path}: the recording measures joint-side torques through a coupled "
                              f"transmission (K not diagonal); replay supports joint-side torques with a diagonal K")
        k = np.diag(K)
        ja, b, fc, fs = k ** 2 * ja, k ** 2 * b, np.abs(k) * fc, np.abs(k) * fs
    return {"motor_inertia": ja, "viscous": b, "coulomb": fc, "static": np.maximum(fs, fc)}


def model_holds_unclipped(model) -> np.ndarray:
    """Per motor: whether the model's friction holds all the recorded torque at rest in the inverse replay (it
    identified no f_s: :func:`js2spec.model.friction_hold_limit`), as the diagnosis predicts it."""
    return np.isinf(friction_hold_limit(model.friction_static))


def model_plant(model, drives, effects=None, effects_source=None) -> Plant:
    """The identified model as a :class:`Plant`: its URDF (``<dynamics>`` tags dropped: the model's friction replaces
    them), ``J_a``, ``B``, ``f_c``, ``f_s`` of ``model.yaml``, no sensor noise, plus ``effects`` (config list)."""
    if list(model.joints) != list(drives.joints):
        raise ReplayError(f"{model.path}: model joints {model.joints} do not match the recording's joints "
                          f"{list(drives.joints)}; replay a recording of the arm the model describes")
    urdf = re.sub(r"<dynamics\b[^>]*/>", "", model.urdf_text)
    arm = _ModelArm("model", urdf, model.urdf_path, drives)
    n = model.n
    p = model_motor_side(model, drives)
    src = str(effects_source or "effects")
    parsed = parse_effects(effects or [], n, source=src, joints=list(drives.joints))
    truth = SimTruth(motor_inertia=p["motor_inertia"], viscous=p["viscous"], coulomb=p["coulomb"],
                     static=p["static"], current_noise_std=np.zeros(n), substeps=2, seed=0, effects=tuple(parsed),
                     source=src)
    return Plant(arm, truth=truth, seed=0)


@dataclass
class InverseReplay:
    """The simulator's torque along a prescribed motor motion (arrays (N, n), motor side)."""
    tau_motor: np.ndarray               # N*m
    temperature_rise: np.ndarray        # K (thermal_drift axes; 0 elsewhere)
    deflection: np.ndarray              # rad (N, ne): link - gear of the elastic joints
    elastic_joints: list[int] = field(default_factory=list)


def inverse_replay(plant: Plant, t, q_motor, dq_motor, ddq_motor, tau_recorded=None,
                   v_rest=None, hold_unclipped=None) -> InverseReplay:
    """Motor torques the plant needs to follow ``(q_motor, dq_motor, ddq_motor)`` sampled at times ``t`` (module
    docstring). Rows with a NaN give NaN and leave the state (temperature, deflections) as it was.

    At rest the torque a motion needs is not one number: friction holds anything up to f_s. With ``tau_recorded``
    (motor side, N*m) and ``v_rest`` (rad/s per motor), a motor slower than ``v_rest`` gets the friction that holds
    the recorded torque, clipped at its f_s (eq. 2-3; what :func:`diagnosis.residual.hold_at_rest` predicts); a
    motor marked in ``hold_unclipped`` (bool per motor: :func:`model_holds_unclipped`, the model identified no f_s)
    holds all of it."""
    q_motor, dq_motor, ddq_motor = (np.asarray(x, float) for x in (q_motor, dq_motor, ddq_motor))
    hold = tau_recorded is not None and v_rest is not None
    if hold:
        tau_recorded, v_rest = np.asarray(tau_recorded, float), np.asarray(v_rest, float)
        resting = at_rest(dq_motor, v_rest)
    t = np.asarray(t, float)
    N, n = q_motor.shape
    d, fr = plant.dyn, plant.friction
    kt = plant.sensors.torque_constant
    ja = d.motor_inertia
    temp = fr.thermal_initial.copy()
    out = np.full((N, n), np.nan)
    temps = np.zeros((N, n))
    ne = d.ne
    defl = np.zeros((N, ne))
    ok = np.all(np.isfinite(q_motor) & np.isfinite(dq_motor) & np.isfinite(ddq_motor), axis=1)
    delta = ddelta = None
    if ne:
        k_s, d_s, half = plant.spring_k, plant.spring_d, plant.spring_half
        first = int(np.flatnonzero(ok)[0]) if ok.any() else 0
        g = d.gravity_link(d.Kp @ q_motor[first] + d.off_p)
        delta = np.zeros(ne)
        for c, j in enumerate(plant.elastic_joints):
            excess = -float(d.perm[:, j] @ g) / k_s[c]
            delta[c] = excess + math.copysign(half[c], excess) if excess != 0 else 0.0
        ddelta = np.zeros(ne)
        m_idx, e_idx = np.arange(n), np.arange(n, n + ne)
    t_prev = None
    for s in range(N):
        if not ok[s]:
            continue
        qm, dqm, ddqm = q_motor[s], dq_motor[s], ddq_motor[s]
        dt = 0.0 if t_prev is None else float(t[s] - t_prev)
        t_prev = t[s]
        if ne:
            steps = max(1, math.ceil(dt / plant.h_max - 1e-9)) if dt > 0 else 1
            h = dt / steps
            for _ in range(steps):
                z = np.concatenate([qm, delta])
                zd = np.concatenate([dqm, ddelta])
                q_link, v_link = d.J @ z + d.off_p, d.J @ zd
                Mz = d.mass_matrix_z(q_link)
                nle = d.J_T @ pin.nonLinearEffects(d.model, d.data, q_link, v_link)
                excess = delta - np.clip(delta, -half, half)
                contact = np.abs(delta) >= half
                q_spring = -k_s * excess - d_s * ddelta * contact
                a_e = np.linalg.solve(Mz[np.ix_(e_idx, e_idx)],
                                      q_spring - nle[e_idx] - Mz[np.ix_(e_idx, m_idx)] @ ddqm)
                if h > 0:
                    ddelta = ddelta + h * a_e
                    delta = delta + h * ddelta
            tau_drive = Mz[np.ix_(m_idx, m_idx)] @ ddqm + Mz[np.ix_(m_idx, e_idx)] @ a_e + nle[m_idx]
            defl[s] = delta
        else:
            tau_drive = d.inverse_dynamics(qm, dqm, ddqm)
        load = tau_drive - ja * ddqm                      # what the gears transmit to the links
        if fr.has_thermal and dt > 0 and s > 0 and np.all(np.isfinite(out[s - 1])):
            current = out[s - 1] / kt                      # the plant's rule: first-order, the held current and
            target = fr.heat_target(current, friction_prev, dq_motor[s - 1])     # friction power
            temp = target + (temp - target) * np.exp(-dt / fr.thermal_time_constant)
        scale = fr.scale(temp) if fr.has_thermal else None
        sign = np.sign(dqm) * fr.active
        fc, fs = fr.levels(sign, scale, load if fr.has_load else None)
        friction_prev = fr.sliding(dqm, sign, fc, fs, scale)
        tau = tau_drive + friction_prev
        if plant.has_cogging:
            k = plant.cog_axes
            tau[k] -= plant.cog_amp * np.sin(plant.cog_periods * qm[k] + plant.cog_phase)
        if plant.has_load_offset:
            tau = tau + plant.load_offset                  # torque_offset: a constant load the drive carries
        if hold:
            rest = resting[s] & np.isfinite(tau_recorded[s])
            if rest.any():
                other = tau - friction_prev
                lim = fs if hold_unclipped is None else np.where(hold_unclipped, np.inf, fs)
                held = np.clip(tau_recorded[s] - other, -lim, lim)
                friction_prev = np.where(rest, held, friction_prev)
                tau = other + friction_prev
        out[s] = tau
        temps[s] = temp
    return InverseReplay(tau_motor=out, temperature_rise=temps, deflection=defl,
                         elastic_joints=list(plant.elastic_joints))


@dataclass
class ForwardReplay:
    """The plant integrated under the recorded torque plus a tracking PD (arrays (N, n), motor side)."""
    q_motor: np.ndarray                 # rad, simulated
    tau_pd: np.ndarray                  # N*m, what the tracking term added to the recorded torque
    bandwidth_hz: float                 # of the tracking term


def forward_replay(plant: Plant, t, q_motor, dq_motor, tau_motor, runs=None, bandwidth_hz: float = 5.0,
                   damping: float = 1.0) -> ForwardReplay:
    """Forward replay: the plant (:meth:`Plant.step`, its integrator, stiction and effects) driven by the recorded
    motor torque ``tau_motor`` plus a tracking term on the recorded motion that keeps it from drifting away, held
    for each sample like a drive's command::

        tau = tau_recorded + M_z(theta) (w^2 (theta_rec - theta) + 2 zeta w (theta_rec_d - theta_d)),
        w = 2 pi bandwidth_hz

    (the plant's own mass matrix: every motor tracks with the same bandwidth whatever its inertia, so the loop is
    as stable on a light wrist as on the shoulder). A model that matches the recording needs little tracking torque
    and follows closely: the simulated positions and the tracking torque are the gaps. The state is reset to the
    recording at the start of every run (``runs``: [start, stop) index pairs of contiguous samples; default one).
    Rows outside the runs, or after the plant left the recording by more than 1 rad, are NaN."""
    q_motor, dq_motor, tau_motor = (np.asarray(x, float) for x in (q_motor, dq_motor, tau_motor))
    t = np.asarray(t, float)
    N, n = q_motor.shape
    runs = runs or [(0, N)]
    d = plant.dyn
    w = 2 * np.pi * bandwidth_hz
    kp, kd = w ** 2, 2 * damping * w
    q_sim = np.full((N, n), np.nan)
    tau_pd = np.full((N, n), np.nan)
    for a, b in runs:
        ok = np.all(np.isfinite(q_motor[a:b]) & np.isfinite(dq_motor[a:b]) & np.isfinite(tau_motor[a:b]), axis=1)
        if not ok.any():
            continue
        plant.reset()
        s0 = a + int(np.argmax(ok))
        plant.set_state(q_motor[s0], dq_motor[s0])
        for s in range(s0, b):
            q, dq = plant.q_motor, plant.dq_motor
            e = q_motor[s] - q
            if not np.all(np.abs(e) < 1.0):
                break                                      # left the recording: the model cannot follow it
            q_sim[s] = q
            if not np.all(np.isfinite(tau_motor[s])) or s + 1 >= b:
                continue
            M = d.mass_matrix_z(d.perm @ plant.q_joint)[:n, :n]      # link angles in pinocchio order
            pd = M @ (kp * e + kd * (dq_motor[s] - dq))
            tau_pd[s] = pd
            plant.step(tau_motor[s] + pd, float(t[s + 1] - t[s]))
    return ForwardReplay(q_motor=q_sim, tau_pd=tau_pd, bandwidth_hz=bandwidth_hz)


def to_motor_side(tau_log: np.ndarray, drives, offsets: np.ndarray | None = None) -> np.ndarray:
    """Recorded torques (N, n) on the motor side (inverse of :func:`to_log_side`): offsets removed, joint-side
    torques carried with ``K^T`` (row-wise ``tau_j K``)."""
    x = tau_log - (0.0 if offsets is None else offsets)
    if str(drives.torque_side) == "joint":
        x = x @ np.asarray(drives.gear_ratio_matrix, float)
    return x


def to_log_side(tau_motor: np.ndarray, drives, offsets: np.ndarray | None = None) -> np.ndarray:
    """Motor torques (N, n) on the recording's torque side (joint: ``K^-T tau_m``, row-wise), plus offsets."""
    out = tau_motor
    if str(drives.torque_side) == "joint":
        out = tau_motor @ np.linalg.inv(np.asarray(drives.gear_ratio_matrix, float))
    return out + (0.0 if offsets is None else offsets)


# ---------------------------------------------------------------------------------------------------- recordings
def load_effects_file(path, n: int, joints: list[str]) -> tuple[list[dict], list[str]]:
    """``effects.yaml`` (``effects:`` list, as ``js2-diagnose`` writes it) -> (effect configs the simulator has,
    notes on those it has not: kinds the diagnosis may name that the simulator does not implement are skipped)."""
    from js2spec.effects import EFFECT_KINDS
    from js2spec.files import load_yaml

    path = Path(path)
    if not path.is_file():
        raise ConfigError(path, None, "effects file not found (js2-diagnose writes OUTDIR/effects.yaml)")
    d = load_yaml(path, "effects file")
    items = d.get("effects") if isinstance(d, dict) else d
    if items is None:
        items = []
    if not isinstance(items, list):
        raise ConfigError(path, "effects", "must be a list of effects")
    keep = [e for e in items if not (isinstance(e, dict) and e.get("kind") not in EFFECT_KINDS
                                     and e.get("kind") in ("coupling", "friction_refit"))]
    notes = [f"{e['kind']} on {e.get('joints')}: not simulated by hil_sim, left out of the replay"
             for e in items if e not in keep]
    parse_effects(keep, n, source=path, joints=joints)          # refuse bad files here, naming the file
    return keep, notes


def recording_motion(log, model):
    """The recording's motion and torque as identification filters them: ``identification.signals.Signals`` with
    the model's cut-offs (``model.yaml`` ``filters``, default 50 Hz velocity / 7 Hz torque), each kept at or below
    0.4 x the sample rate."""
    from identification.signals import FilterSettings, from_log

    f = (model.raw.get("filters") or {})
    fs = float(log.cycle_hz)
    fv = min(float(f.get("velocity_cutoff_hz") or 50.0), 0.4 * fs)
    fa = min(float(f.get("acceleration_cutoff_hz") or 7.0), fv)
    return from_log(log, FilterSettings(fc_velocity_hz=fv, fc_acceleration_hz=fa, order=int(f.get("order") or 4)))


def rms_per_joint(err: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """RMS over ``rows`` (bool (N,) or (N, n)) of each column of ``err`` (N, n); NaN where a column has no row."""
    rows = np.broadcast_to(rows if rows.ndim == 2 else rows[:, None], err.shape)
    out = np.full(err.shape[1], np.nan)
    for i in range(err.shape[1]):
        r = rows[:, i] & np.isfinite(err[:, i])
        if r.any():
            out[i] = float(np.sqrt(np.mean(err[r, i] ** 2)))
    return out


@dataclass
class RecordingReplay:
    """A recording replayed through the model and through the model plus effects (log side, filtered like the
    recorded torque): the inverse replay's torques, the forward replay's positions and tracking torques."""
    t: np.ndarray
    tau_meas: np.ndarray                # N*m, filtered like identification filters torque
    tau_model: np.ndarray               # N*m, inverse replay of the model, same filter
    tau_effects: np.ndarray | None      # N*m, inverse replay of the model + effects, same filter
    tau_effects_raw: np.ndarray         # N*m, unfiltered (what the simulated recording carries)
    rows: np.ndarray                    # (N, n) bool: usable and moving (>= min_speed rad/s at the joint)
    joints: list[str]
    notes: list[str]
    signals: object
    forward: list = field(default_factory=list)    # ForwardReplay of the model (and of the model + effects)

    def rms(self, which: str, rows: np.ndarray | None = None) -> np.ndarray:
        """Per joint RMS of recorded - simulated torque (inverse replay), on ``rows`` (default: moving samples)."""
        tau = self.tau_model if which == "model" else self.tau_effects
        return rms_per_joint(self.tau_meas - tau, self.rows if rows is None else rows & self.rows)

    def position_rms(self, which: str, rows: np.ndarray | None = None) -> np.ndarray:
        """Per joint RMS of recorded - simulated joint angle (forward replay, rad) on ``rows`` (default: usable)."""
        fr = self.forward[0 if which == "model" else -1]
        K = np.asarray(self.signals.extra["K"], float)
        err = (self.signals.q_motor - fr.q_motor) @ K.T                  # joint side: K (theta_rec - theta_sim)
        keep = self.signals.keep[:, None] if rows is None else rows
        return rms_per_joint(np.where(np.isfinite(fr.q_motor), err, np.nan), keep & np.ones_like(err, bool))

    def followed(self, which: str) -> float:
        """Share of the usable samples the forward replay followed (did not leave the recording by 1 rad)."""
        fr = self.forward[0 if which == "model" else -1]
        keep = self.signals.keep
        return float(np.mean(np.isfinite(fr.q_motor[keep, 0]))) if keep.any() else 0.0


def replay_recording(recording, model_path, effects_path=None, min_speed: float = 0.01,
                     forward: bool = True, bandwidth_hz: float = 5.0, hold_at_rest: bool = True) -> RecordingReplay:
    """Replay ``recording`` (a js2 log) through the model in ``model_path`` and, with ``effects_path``, through the
    model plus those effects: inverse replay (torques) and, with ``forward``, forward replay (positions and the
    tracking torque at ``bandwidth_hz``); module docstring. ``hold_at_rest``: a motor slower than ``min_speed`` (at
    the joint) gets the friction that holds the recorded torque up to f_s, as the diagnosis predicts
    (:func:`inverse_replay`); False: the sliding law there too (``bench_diagnose``'s visibility yardstick)."""
    from js2spec.log import read_log
    from js2spec.model import load_model

    model = load_model(model_path)
    log = read_log(recording)
    drives = log.drives
    problem = model.recording_mismatch(drives)
    if problem is not None:
        what, text = problem
        model_side = str(model.raw.get("torque_side", drives.torque_side))
        advice = ("replay a recording of the arm the model describes" if what == "joints" else
                  f"replay a recording with {model_side}-side torques")
        raise ReplayError(f"{recording}: {text} ({model.path}); {advice}")
    notes: list[str] = []
    effects = []
    if effects_path is not None:
        effects, notes = load_effects_file(effects_path, model.n, list(drives.joints))
    sig = recording_motion(log, model)
    K = np.asarray(drives.gear_ratio_matrix, float)
    sig.extra["K"] = K
    off = model.torque_offset
    tau_rec_motor = to_motor_side(sig.tau, drives, off)
    tau_held = to_motor_side(sig.tau_raw, drives, off)           # what friction holds at rest (unfiltered)
    v_rest = motor_rest_speed(min_speed, K)                     # motor side: the diagnosis' rest threshold
    # filtered like the torque below: made from the acceleration before that filter (as the diagnosis predicts)
    ddq_motor = sig.acceleration_unfiltered()
    runs, fwd = [], []
    for eff in ([[]] + ([effects] if effects_path is not None else [])):
        plant = model_plant(model, drives, eff, effects_path)
        rep = inverse_replay(plant, sig.t, sig.q_motor, sig.dq_motor, ddq_motor,
                             tau_recorded=tau_held if hold_at_rest else None, v_rest=v_rest,
                             hold_unclipped=model_holds_unclipped(model))
        runs.append(to_log_side(rep.tau_motor, drives, off))
        if forward:
            fwd.append(forward_replay(model_plant(model, drives, eff, effects_path), sig.t, sig.q_motor,
                                      sig.dq_motor, tau_rec_motor, runs=sig.runs, bandwidth_hz=bandwidth_hz))
    moving = np.abs(np.nan_to_num(sig.dq_motor) @ K.T) >= min_speed
    good = sig.keep[:, None] & moving & np.isfinite(sig.tau)
    filt = [sig.filter_like_torque(np.nan_to_num(r)) for r in runs]
    return RecordingReplay(t=sig.t, tau_meas=sig.tau, tau_model=filt[0], tau_effects=filt[1] if len(filt) > 1 else None,
                           tau_effects_raw=runs[-1], rows=good, joints=list(drives.joints), notes=notes, signals=sig,
                           forward=fwd)


def _copy_event(w, e: dict) -> None:
    w.event(e["t"], e["kind"], e["trial"], **{a: b for a, b in e.items() if a not in ("t", "kind", "trial")})


def write_replay_log(rep: RecordingReplay, recording, model_path, out, effects_path=None,
                     mode: str = "inverse") -> Path:
    """The simulated recording (the model plus the effects when given), with the recording's events.
    ``inverse``: the recorded motor positions and the simulator's torque (unfiltered). ``forward``: the positions
    the plant reached and the torque that drove it (recorded + tracking), invalid where it left the recording.
    Torques on the recording's torque side, current ``tau / k_t`` for motor-side torques."""
    from js2spec.log import LogWriter, read_log
    from js2spec.model import load_model

    log = read_log(recording)
    model = load_model(model_path)
    sig = rep.signals
    drives = log.drives
    fs = sig.fs
    if mode == "forward":
        fr = rep.forward[-1]
        tau_raw = to_log_side(to_motor_side(sig.tau, drives, model.torque_offset) + fr.tau_pd, drives,
                              model.torque_offset)
        q_out = fr.q_motor
    else:
        tau_raw, q_out = rep.tau_effects_raw, sig.q_motor_raw
    valid = np.all(np.isfinite(tau_raw), axis=1) & np.all(np.isfinite(q_out), axis=1)
    kt = np.asarray(drives.torque_constant, float)
    tau = np.nan_to_num(tau_raw)
    current = None
    if str(drives.torque_side) == "motor":
        current = tau / np.where(kt > 0, kt, 1.0)
    t0 = float(sig.t[0])
    with LogWriter(out, robot=log.robot, cycle_hz=log.cycle_hz, source="hil_sim:replay", urdf_text=model.urdf_text,
                   drives_yaml=log.drives_yaml) as w:
        ev = sorted(log.events, key=lambda e: e["t"])
        ei = 0
        for k in range(len(sig.t)):
            tk = float(sig.t[k])
            while ei < len(ev) and ev[ei]["t"] <= tk:
                _copy_event(w, ev[ei])
                ei += 1
            w.feedback(int(round((tk - t0) * fs)), tk, np.nan_to_num(q_out[k]), tau[k],
                       motor_current=None if current is None else current[k], valid=[bool(valid[k])] * len(kt))
        while ei < len(ev):
            _copy_event(w, ev[ei])
            ei += 1
        w.metadata("replay", {"recording": str(recording), "model": str(model.path), "mode": f"{mode} replay",
                              "effects": str(effects_path) if effects_path else "none"})
    return Path(out)
