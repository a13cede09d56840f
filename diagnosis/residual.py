"""What the model predicts on a recording, and what it leaves: the residual, motor side (eq. 1).

The prediction uses the exported model exactly as users load it: the identified URDF's inertial parameters, the
motor inertias J_a and the friction B, f_c of ``model.yaml`` (eq. 1), evaluated on the recording's signals filtered
as identification filters them (50 Hz velocity, 7 Hz acceleration and torque, zero phase).

Friction is undefined at rest (stiction holds any torque below f_s), so samples where a motor turns slower than
``min_speed`` are left out of that motor's residual (``mask``); so are trimmed edges and lost cycles.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from identification.regressor import arm_model, build_regressor, standard_vector
from identification.signals import FilterSettings, Signals, from_log
from identification.trials import trial_spans
from js2spec.errors import Js2Error
from js2spec.model import IdentifiedModel


class DiagnosisError(Js2Error):
    """The model and the recording cannot be compared (different arm, no usable samples, ...)."""


@dataclass
class ResidualData:
    """Everything a candidate term needs, on the recording's sample grid. Arrays (N, n) motor side unless said."""

    log_path: str
    t: np.ndarray                 # (N,) s
    fs: float
    q_motor: np.ndarray           # rad
    dq_motor: np.ndarray          # rad/s
    ddq_motor: np.ndarray         # rad/s^2
    q_joint: np.ndarray           # rad, K q_motor + offset
    tau_meas: np.ndarray          # N*m measured, filtered like the acceleration
    tau_meas_raw: np.ndarray      # N*m measured, unfiltered
    tau_pred: np.ndarray          # N*m predicted by the model (eq. 1), through the same filter
    tau_pred_raw: np.ndarray      # N*m predicted by the model, unfiltered (for the wide-band residual)
    W_rigid_motor: np.ndarray     # (N, n, 10 n) K^T Y: rigid-body regressor, motor side, unfiltered
    tau_rigid_joint: np.ndarray   # N*m joint side: M q_dd + h + g predicted (the load the gears carry)
    tau_rigid_motor: np.ndarray   # N*m motor side: K^T (M q_dd + h + g)
    friction_pred: np.ndarray     # N*m motor side: B dq_m + f_c sgn(dq_m) of the model
    motor_current: np.ndarray     # A (measured, unfiltered)
    mask: np.ndarray              # (N, n) bool: usable for this motor
    fit_rows: np.ndarray          # (N,) bool: rows the candidate terms are fitted on
    holdout_rows: np.ndarray      # (N,) bool: rows only scored, never fitted
    K: np.ndarray
    joints: list[str]
    arm: object
    signals: Signals
    split_note: str = ""
    extra: dict = field(default_factory=dict)

    @property
    def n(self) -> int:
        return self.q_motor.shape[1]

    @property
    def residual(self) -> np.ndarray:
        """Measured minus predicted motor torque in the torque's band (filtered like the acceleration)."""
        return self.tau_meas - self.tau_pred

    @property
    def residual_wide(self) -> np.ndarray:
        """Measured minus predicted motor torque, unfiltered (ripple above the 7 Hz band stays in)."""
        return self.tau_meas_raw - self.tau_pred_raw

    def lowpass(self, X: np.ndarray) -> np.ndarray:
        """Filter a feature (N, ...) exactly as the measured torque was filtered (parallel filtering)."""
        shp = X.shape
        flat = X.reshape(shp[0], -1)
        return self.signals.filter_like_torque(np.nan_to_num(flat)).reshape(shp)


def _trial_rows(log, t: np.ndarray, trial: str) -> np.ndarray:
    """Rows of the signal grid inside the spans of ``trial``."""
    rows = np.zeros(len(t), dtype=bool)
    for span in trial_spans(log.events, float(t[-1])):
        if span.name == trial:
            rows |= (t >= span.t0) & (t <= span.t1)
    return rows


def residual_data(model: IdentifiedModel, log, *, holdout_trial: str = "validation", fit_trials=None,
                  min_speed: float = 1.0, settings: FilterSettings | None = None,
                  holdout_fraction: float = 1 / 3) -> ResidualData:
    """Predict the recording with the model and split it into fit and held-out rows.

    Held-out rows: the ``holdout_trial`` (default ``validation``) when the log has it, else the last
    ``holdout_fraction`` of the recording. Fit rows: ``fit_trials`` (default: every other trial, or the rest).
    """
    drives = log.drives
    if list(model.joints) != list(drives.joints):
        raise DiagnosisError(f"{model.path}: model joints {model.joints} do not match the log's joints "
                             f"{drives.joints} ({log.path}); diagnose a recording of the arm the model describes")
    if drives.torque_side != "motor":
        raise DiagnosisError(f"{log.path}: torque_side is {drives.torque_side!r}; diagnosis works on motor-side "
                             "torques (eq. 1)")
    arm = arm_model(model.urdf_text, drives, urdf_name=str(model.urdf_path))
    sig = from_log(log, settings)
    N, n = sig.q_motor.shape
    K = np.asarray(drives.gear_ratio_matrix, float)
    good = np.all(np.isfinite(sig.q_motor), axis=1) & np.all(np.isfinite(sig.tau), axis=1)
    rows = np.flatnonzero(good)
    qm, dqm, ddqm = sig.q_motor[rows], sig.dq_motor[rows], sig.ddq_motor[rows]
    W = build_regressor(arm, qm, dqm, ddqm)
    pi = standard_vector(arm, motor_inertia=model.motor_inertia, viscous=model.friction_viscous,
                         coulomb=model.friction_coulomb)
    tau_pred = np.full((N, n), np.nan)
    tau_pred[rows] = W @ pi
    nl = 10 * n
    W_rigid = np.zeros((N, n, nl))
    W_rigid[rows] = W[:, :, :nl]
    del W
    rigid_motor = np.full((N, n), np.nan)
    rigid_motor[rows] = W_rigid[rows] @ pi[:nl]
    rigid_joint = np.full((N, n), np.nan)
    rigid_joint[rows] = rigid_motor[rows] @ np.linalg.inv(K)        # tau_joint = K^-T tau_motor
    friction = np.full((N, n), np.nan)
    friction[rows] = model.friction_viscous * dqm + model.friction_coulomb * np.sign(dqm)
    # parallel filtering: the prediction passes the torque's filter too
    tau_pred_f = np.full((N, n), np.nan)
    tau_pred_f[rows] = sig.filter_like_torque(np.nan_to_num(tau_pred))[rows]
    kt = np.asarray(drives.torque_constant, float)
    current = sig.tau_raw / kt

    t = sig.t - sig.t[0]
    keep = sig.keep & good
    mask = keep[:, None] & (np.abs(np.nan_to_num(sig.dq_motor)) >= min_speed)
    trials = log.trials()
    if holdout_trial in trials:
        hold = _trial_rows(log, sig.t, holdout_trial)
        if not fit_trials and "excitation" in trials:
            fit_trials = ["excitation"]
        if fit_trials:
            fit = np.zeros(N, dtype=bool)
            for tr in fit_trials:
                fit |= _trial_rows(log, sig.t, tr)
        else:
            fit = ~hold
        note = f"fit on {', '.join(fit_trials or [x for x in trials if x != holdout_trial]) or 'the rest'}; " \
               f"held out: the '{holdout_trial}' trial"
    else:
        cut = t[keep][0] + (1 - holdout_fraction) * (t[keep][-1] - t[keep][0]) if keep.any() else 0
        hold = t >= cut
        fit = ~hold
        note = f"no '{holdout_trial}' trial: fit on the first {1 - holdout_fraction:.0%} of the recording, " \
               f"held out: the last {holdout_fraction:.0%}"
    fit &= keep
    hold &= keep
    if not (mask & fit[:, None]).any() or not (mask & hold[:, None]).any():
        raise DiagnosisError(f"{log.path}: not enough moving samples to fit and hold out "
                             f"(fit rows {int(fit.sum())}, held-out rows {int(hold.sum())}); record an excitation "
                             "and a validation trial")
    return ResidualData(log_path=str(log.path), t=t, fs=sig.fs, q_motor=sig.q_motor, dq_motor=sig.dq_motor,
                        ddq_motor=sig.ddq_motor, q_joint=arm.joint_from_motor(sig.q_motor), tau_meas=sig.tau,
                        tau_meas_raw=sig.tau_raw, tau_pred=tau_pred_f, tau_pred_raw=tau_pred,
                        W_rigid_motor=W_rigid, tau_rigid_joint=rigid_joint,
                        tau_rigid_motor=rigid_motor, friction_pred=friction, motor_current=current, mask=mask,
                        fit_rows=fit, holdout_rows=hold, K=K, joints=list(drives.joints), arm=arm, signals=sig,
                        split_note=note, extra={"model": model, "min_speed": min_speed})
