"""What the model predicts on a recording, and what it leaves: the residual, motor side (eq. 1).

The prediction uses the exported model exactly as users load it: the identified URDF's inertial parameters, the
motor inertias J_a, the friction B, f_c of ``model.yaml`` (eq. 1), its torque offsets and its sqrt-viscous friction
Bs sgn(v) sqrt|v| when it has them, evaluated
on the recording's signals filtered as identification filters them (zero phase; the cut-offs of ``model.yaml``'s
``filters``, kept below the recording's Nyquist frequency by :func:`model_cutoffs`).

Joint-side torques (``torque_side: joint``, torque sensors behind the gears, the model identified on that side) are
predicted on the joint side and then carried to the motor side with K^T (tau_m = K^T tau_j), like every term of the
library; with K = I nothing changes.

Friction is undefined at rest (stiction holds any torque below f_s), so samples where a joint turns slower than
``min_speed`` (rad/s at the joint, so the same number suits a 1:100 harmonic drive and a direct drive) are left out of
that motor's residual (``mask``); so are trimmed edges and lost cycles.

Three parts of the recording (honest proof): ``fit_rows`` (a term's coefficients and hyper-parameter),
``select_rows`` (which terms the search ranks and accepts) and ``holdout_rows`` (the report: the gains printed and
drawn; never seen by the search). See :func:`split_rows`.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.signal import butter, sosfilt, sosfilt_zi

from identification.regressor import arm_model, build_regressor, standard_vector
from identification.signals import (NYQUIST_MARGIN, PAPER_FC_ACCELERATION_HZ, PAPER_FC_VELOCITY_HZ, FilterSettings,
                                    Signals, choose_cutoffs, filtfilt_padlen, from_log)
from identification.trials import trial_spans
from js2spec.drives import at_rest, motor_rest_speed
from js2spec.errors import Js2Error
from js2spec.log import read_log
from js2spec.model import IdentifiedModel, friction_hold_limit

from .filter_kernel import filtfilt_rows_into, filtfilt_rows_kernel


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
    ddq_motor: np.ndarray         # rad/s^2, before the torque's filter (every column passes it: ``lowpass``)
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
    fit_rows: np.ndarray          # (N, n) bool: rows the candidate terms are fitted on, per motor (:func:`split_rows`)
    holdout_rows: np.ndarray      # (N, n) bool: report rows: only scored for the report, never seen by the search
    K: np.ndarray
    joints: list[str]
    arm: object
    signals: Signals
    split_note: str = ""
    extra: dict = field(default_factory=dict)
    select_rows: np.ndarray | None = None   # (N, n) bool: rows the search ranks and accepts terms on
    min_speed_motor: np.ndarray | None = None   # (n,) rad/s motor: the per-motor speed threshold of ``mask``
    torque_side: str = "motor"    # side the log measured (the arrays here are all motor side)
    at_rest: np.ndarray | None = None   # (N, n) bool: motor slower than its min_speed_motor threshold (friction holds)
    torque_step_motor: np.ndarray | None = None   # (n,) N*m: one count of the drive's current read-back (motor side)

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
        return np.ascontiguousarray(self.lowpass_series(X.reshape(shp[0], -1).T).T).reshape(shp)

    def lowpass_series(self, XT: np.ndarray, runs=None, keep: np.ndarray | None = None) -> np.ndarray:
        """:meth:`lowpass` of M series given as the rows of XT (M, N), time along the last axis (the layout the
        filter runs along without copying); returns (M, N). NaN counts as 0. ``runs``: the stretches of XT's time
        axis filtered each on its own (default: the recording's runs, ``signals.runs``; :meth:`lowpass_spans`'
        spans laid end to end). ``keep`` ((N,) bool): return only those samples, (M, keep.sum()) — the same numbers
        as ``lowpass_series(XT, runs)[:, keep]``, written there by the filter itself (no (M, N) result to copy
        from; a kept sample outside every run reads 0)."""
        if not np.isfinite(XT).all():
            XT = np.nan_to_num(XT)
        sos, zi = self._sos(), self._sos_zi()
        spans = self.signals.runs if runs is None else runs
        if keep is None:
            out = np.empty(XT.shape, dtype=float)
            for a, b in spans:
                out[:, a:b] = filtfilt_rows(sos, zi, XT[:, a:b], filtfilt_padlen(sos, b - a))
            return out
        keep = np.asarray(keep, dtype=bool)
        X = np.asarray(XT, dtype=float)
        out = np.zeros((X.shape[0], int(keep.sum())))      # a kept sample outside every run: 0 (not filtered)
        at = np.cumsum(keep) - keep          # each kept sample's column in out
        for a, b in spans:
            cols = np.flatnonzero(keep[a:b])
            if not len(cols):
                continue
            o = int(at[a + cols[0]])
            filtfilt_rows_into(sos, zi, X[:, a:b], filtfilt_padlen(sos, b - a), cols.astype(np.int64),
                               out[:, o:o + len(cols)])
        return out

    def lowpass_adjoint(self, b: np.ndarray, runs=None, keep: np.ndarray | None = None) -> np.ndarray:
        """The transpose of :meth:`lowpass_series` applied to b: v (N,) with ``lowpass_series(XT, runs, keep) @ b``
        = ``XT @ v`` for every XT (M, N), to rounding. ``b``: (keep.sum(),), or (N,) without ``keep``. So X_f^T b
        of many filtered series costs one filtering of b backwards (per run: the zero-phase filter's two passes
        transposed, the initial states' and the odd extension's terms added) and the series' dot products with v,
        instead of filtering each series. Samples outside every run get 0 (they are not filtered)."""
        sos, zi = self._sos(), self._sos_zi().reshape(-1, 2)
        spans = self.signals.runs if runs is None else runs
        n_all = len(self.t) if keep is None else len(keep)
        full = np.zeros(n_all)
        if keep is None:
            full[:] = b
        else:
            full[np.asarray(keep, dtype=bool)] = b
        v = np.zeros(n_all)
        for a, e in spans:
            L = e - a
            u = full[a:e]
            if L <= 0 or not np.any(u):
                continue
            P = filtfilt_padlen(sos, L)
            Le = L + 2 * P
            r = sosfilt(sos, np.zeros(Le), zi=zi)[0]       # the passes' response to their initial state (per unit)
            y = np.zeros(Le)
            y[P:P + L] = u                                  # the output's samples, transposed
            y_adj = sosfilt(sos, y)                         # the backward pass transposed: a forward pass ...
            y_adj[-1] += float(r[::-1] @ y)                 # ... and its initial state, set by the last sample
            e_adj = sosfilt(sos, y_adj[::-1])[::-1]         # the forward pass transposed: a backward pass ...
            e_adj[0] += float(r @ y_adj)                    # ... and its initial state, set by the first sample
            x_adj = e_adj[P:P + L].copy()                   # the odd extension transposed
            if P:
                k = np.arange(P)
                x_adj[0] += 2.0 * e_adj[:P].sum()
                np.subtract.at(x_adj, P - k, e_adj[:P])
                x_adj[L - 1] += 2.0 * e_adj[P + L:].sum()
                np.subtract.at(x_adj, L - 2 - k, e_adj[P + L:])
            v[a:e] += x_adj
        return v

    def _sos(self) -> np.ndarray:
        sos = self.extra.get("sos")
        if sos is None:       # the torque's filter (Signals.filter_like_torque), designed once per recording
            st = self.signals.settings
            sos = self.extra["sos"] = butter(st.order, st.fc_acceleration_hz, btype="low", fs=self.fs, output="sos")
        return sos

    def _sos_zi(self) -> np.ndarray:
        """:meth:`_sos`' initial state for a unit step, (sections, 1, 2) (the layout :func:`filtfilt_rows` takes),
        made once per recording."""
        zi = self.extra.get("sos_zi")
        if zi is None:
            sos = self._sos()
            zi = self.extra["sos_zi"] = sosfilt_zi(sos).reshape(len(sos), 1, 2)
        return zi

    MEMORY = 1e-24      # lowpass_spans: what the filter remembers of a sample this far back (of its peak response)

    def lowpass_spans(self, rows: np.ndarray) -> list[tuple[int, int]] | None:
        """Stretches [a, b) of the time axis whose filtering alone (:meth:`lowpass_series` with these as ``runs``)
        gives :meth:`lowpass`'s values on ``rows`` ((N,) bool): each run cut to the rows in it plus the filter's
        memory on either side (samples until its slowest pole has decayed to ``MEMORY``, at least 4 pads), never
        beyond the run. Where a stretch ends at its run's end the filter starts there as on the whole run (the same
        numbers); where it ends inside the run the start differs, but by less than ``MEMORY`` of the signal once it
        reaches the rows: far below a double's rounding (the rounding then makes the two the same numbers, or a
        unit in the last place apart). None where some of ``rows`` lie outside every run, or there are no rows (filter
        the whole)."""
        sos = self._sos()
        r = max(float(np.max(np.abs(np.roots(sec[3:])))) for sec in sos)
        reach = max(int(np.ceil(np.log(self.MEMORY) / np.log(r))), 4 * 3 * (2 * len(sos) + 1) * 4) if r > 0 else 0
        spans, inside = [], 0
        for a, b in self.signals.runs:
            idx = np.flatnonzero(rows[a:b])
            inside += len(idx)
            if not len(idx):
                continue
            # rows further apart than twice the memory: separate stretches
            cut = np.flatnonzero(np.diff(idx) > 2 * reach)
            for lo, hi in zip(np.r_[idx[0], idx[cut + 1]], np.r_[idx[cut], idx[-1]]):
                spans.append((max(a, a + lo - reach), min(b, a + hi + 1 + reach)))
        return spans if spans and inside == int(rows.sum()) else None


def filtfilt_rows(sos: np.ndarray, zi: np.ndarray, x: np.ndarray, padlen: int) -> np.ndarray:
    """``scipy.signal.sosfiltfilt(sos, x, axis=-1, padlen=padlen)`` (odd extension) of the rows of x (M, L), with the
    filter's initial state ``zi = sosfilt_zi(sos).reshape(len(sos), 1, 2)`` made once per recording instead of once
    per call (solving a linear system per section each time: 1.3 CPU s of the speed bench's search). The same steps
    as scipy's, on the same numbers, compiled and 8 series at a time (:mod:`diagnosis.filter_kernel`): the same
    result to the bit (``tests/test_diag_exact_speedups.py``)."""
    if x.shape[-1] <= padlen:
        raise ValueError(f"filtfilt_rows: {x.shape[-1]} samples, padlen {padlen}")
    return filtfilt_rows_kernel(np.asarray(sos, dtype=float), np.asarray(zi, dtype=float),
                                np.asarray(x, dtype=float), int(padlen))


def model_cutoffs(fs: float, model: IdentifiedModel | None = None) -> FilterSettings:
    """Filter cut-offs for a recording sampled at ``fs`` Hz: those the model was identified with (``model.yaml``
    ``filters``; else the paper's 50 Hz velocity / 7 Hz acceleration), each kept at or below identification's
    ``NYQUIST_MARGIN`` x Nyquist (0.4 fs: at 100 Hz, 40 Hz velocity, 7 Hz acceleration), the acceleration's never
    above the velocity's; :func:`identification.signals.choose_cutoffs` checks them and says why (``reason``)."""
    f = (model.raw.get("filters") if model is not None else None) or {}
    top = NYQUIST_MARGIN * fs / 2
    fv = min(float(f.get("velocity_cutoff_hz") or PAPER_FC_VELOCITY_HZ), top)
    fa = min(float(f.get("acceleration_cutoff_hz") or PAPER_FC_ACCELERATION_HZ), fv)
    return choose_cutoffs(fs, fc_velocity_hz=fv, fc_acceleration_hz=fa, order=int(f.get("order") or 4))


def _trial_rows(log, t: np.ndarray, trial: str) -> np.ndarray:
    """Rows of the signal grid inside the spans of ``trial``."""
    rows = np.zeros(len(t), dtype=bool)
    for span in trial_spans(log.events, float(t[-1])):
        if span.name == trial:
            rows |= (t >= span.t0) & (t <= span.t1)
    return rows


def _blocks(pool: np.ndarray, t: np.ndarray, blocks: int = 15) -> np.ndarray:
    """(N,) int: the interleave's time block of every row (see :func:`interleave`), anchored on ``pool``."""
    tp = t[pool]
    length = float(np.clip((tp[-1] - tp[0]) / blocks, 0.5, 10.0))
    return np.floor((t - tp[0]) / length).astype(int)


def interleave(pool: np.ndarray, t: np.ndarray, blocks: int = 15) -> tuple[np.ndarray, np.ndarray]:
    """Split the rows ``pool`` into fit and select rows by interleaved time blocks (fit, fit, select, ...), so both
    see the whole motion and the whole session while no sample is in both. Block length: the pool's span /
    ``blocks``, within 0.5-10 s. (A forward split — fit first, select after — was tried: on an 8.5 s real recording
    the fit part then covers too little of the motion and a clean recording got a payload named.)"""
    if not pool.any():
        return pool.copy(), pool.copy()
    sel = pool & (_blocks(pool, t, blocks) % 3 == 2)
    return pool & ~sel, sel


#: In the time split, a joint that has less than this share of its moving samples before the recording's report cut
#: (nominally 1 - report_fraction, 70 %) gets a cut of its own: the time by which 1 - report_fraction of its moving
#: samples are past (:func:`split_rows`). On the independent simulator some trajectories move a joint only late in
#: the session (case 77: joints 1-4 at rest 73-79 % of the time, their motion all but one sample in the last 30 %),
#: so the search had no fit rows there and could not see the friction on joint 3 that the report rows showed.
MIN_SHARE_BEFORE_CUT = 0.5


def split_rows(log, t: np.ndarray, keep: np.ndarray, holdout_trial: str = "validation", fit_trials=None,
               report_fraction: float = 0.3, moving: np.ndarray | None = None
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, str]:
    """Fit, select and report rows (see the module docstring): (N,) bool each, or (N, n) per motor when ``moving``
    ((N, n) bool: the rows where each motor is usable) is given.

    * With a ``holdout_trial`` (default ``validation``) beside other usable rows — a second trajectory: FIT is the
      other trials (``fit_trials``, default ``excitation`` when present, else every usable row outside it); the
      holdout trial is cut by :func:`interleave` into REPORT (2/3) and SELECT (1/3) time blocks. So a term is
      accepted only if it holds on a trajectory it was not fitted on (a term locked to the excitation's timing —
      a repeated excitation puts the same motion in every block — no longer passes SELECT), and the report rows
      are that same second trajectory, never seen by the search. Every motor has the same rows.
    * Otherwise (no labels, or a recording whose only trial is ``validation``): REPORT is the last
      ``report_fraction`` of the recording's usable time; FIT and SELECT the rest, by :func:`interleave` (2/3 fit,
      1/3 select). With ``moving``, a motor whose motion lies mostly at the end (less than
      ``MIN_SHARE_BEFORE_CUT`` of its moving samples before that cut) is cut later, where 1 - ``report_fraction``
      of its own moving samples are past: its report rows are then its own last ``report_fraction``, and the
      search still never sees a motor's report rows.
    """
    n = None if moving is None else moving.shape[1]

    def per_motor(*rows):
        return tuple(r if n is None else part_rows(r, n) for r in rows)

    trials = log.trials()
    hold = _trial_rows(log, t, holdout_trial) & keep if holdout_trial in trials else np.zeros(len(t), bool)
    if hold.any() and (keep & ~hold).sum() >= 0.2 * keep.sum():
        if not fit_trials and "excitation" in trials:
            fit_trials = ["excitation"]
        if fit_trials:
            pool = np.zeros(len(t), dtype=bool)
            for tr in fit_trials:
                pool |= _trial_rows(log, t, tr)
            names = ", ".join(fit_trials)
        else:
            pool = ~hold
            names = ", ".join(x for x in trials if x != holdout_trial) or "the rest of the recording"
        fit = pool & keep & ~hold
        report, sel = interleave(hold, t)
        return (*per_motor(fit, sel, report), (f"fit on {names}; select and report on the '{holdout_trial}' trial "
                                              "(select : report = 1 : 2, interleaved time blocks)"))
    tk = t[keep]
    cut = tk[0] + (1 - report_fraction) * (tk[-1] - tk[0]) if len(tk) else 0.0
    hold = keep & (t >= cut)
    pool = keep & ~hold
    why = (f"the '{holdout_trial}' trial is the whole recording" if holdout_trial in trials
           else f"no '{holdout_trial}' trial")
    note = (f"{why}: time split, fit and select on the first {1 - report_fraction:.0%} of the recording, "
            f"report: the last {report_fraction:.0%}")
    fit, sel = interleave(pool, t)
    if n is None:
        return fit, sel, hold, note + " (fit : select = 2 : 1, interleaved time blocks)"
    fit, sel, hold = per_motor(fit, sel, hold)
    block = _blocks(pool, t) if pool.any() else np.zeros(len(t), int)
    late = []
    for j in range(n):
        mine = keep & moving[:, j]
        total = int(mine.sum())
        if total == 0 or (mine & pool).sum() >= MIN_SHARE_BEFORE_CUT * total:
            continue
        own_cut = float(np.quantile(t[mine], 1 - report_fraction))
        before = keep & (t < own_cut)
        hold[:, j] = keep & (t >= own_cut)
        sel[:, j] = before & (block % 3 == 2)
        fit[:, j] = before & ~sel[:, j]
        late.append(f"motor {j + 1} at {own_cut - tk[0]:.1f} s ({(mine & pool).sum() / total:.0%} of its motion "
                    "before the recording's cut)")
    if late:
        note += (f"; cut later for the motors that move mostly at the end, where {1 - report_fraction:.0%} of their "
                 "own motion is past: " + ", ".join(late))
    return fit, sel, hold, note + " (fit : select = 2 : 1, interleaved time blocks)"


def part_rows(rows: np.ndarray, n: int) -> np.ndarray:
    """(N, n) bool: a part of the rows (``ResidualData.fit_rows``, ``select_rows`` or ``holdout_rows``) per motor;
    a part given as (N,) rows is the same for every motor."""
    rows = np.asarray(rows, bool)
    return rows if rows.ndim == 2 else np.repeat(rows[:, None], n, axis=1)


def motor_rows(rows: np.ndarray, j: int) -> np.ndarray:
    """(N,) bool: motor j's rows of a part (:func:`part_rows`; (N,) rows are every motor's)."""
    rows = np.asarray(rows, bool)
    return rows[:, j] if rows.ndim == 2 else rows


def torque_step(drives, tau_motor: np.ndarray | None = None) -> np.ndarray | None:
    """One count of each drive's current read-back as a motor torque (N*m): CiA 402 reports the current in per-mille
    of the rated current (0x6078 / 0x6075), so a count is k_t I_rated / 1000. When the drives do not give their rated
    current (an imported recording's drives.yaml), the count is read from the recorded motor torques ``tau_motor``
    (N, n) themselves where they sit on a grid (:func:`torque_step_from_data`). None for joint-side torques, or when
    neither says the resolution."""
    if str(drives.torque_side) != "motor":
        return None
    rated = getattr(drives, "rated_current", None)
    if rated is None:
        step = None if tau_motor is None else torque_step_from_data(tau_motor)
        return step if step is not None and np.isfinite(step).any() else None
    return np.abs(np.asarray(drives.torque_constant, float)) * np.asarray(rated, float) / 1000.0


#: a motor's torques are on a grid of step q when this share of them is within 2 % of a step of a multiple of q
GRID_SHARE = 0.99


def torque_step_from_data(tau_motor: np.ndarray) -> np.ndarray:
    """Per motor, the step of the grid its recorded torques (N, n; N*m) sit on -- the read-back's resolution -- or
    nan when they do not sit on one (nearly every value distinct, or the smallest difference between two values not
    a common step of them). The smallest positive difference between the distinct values (above float rounding) is
    the candidate step q; it is kept when :data:`GRID_SHARE` of the values are within 2 % of q of a multiple of q.

    A recording exported with few decimals gives its print precision (the real TX40's 5e-8-1e-7 N*m): a count that
    small never holds a term back. The independent simulator's drives report 1e-4 N*m steps
    (scripts/bench_diagnose_foreign.py): without the count, a 2e-5 N*m torque offset on its wrist was named."""
    tau = np.asarray(tau_motor, float)
    out = np.full(tau.shape[1], np.nan)
    for j in range(tau.shape[1]):
        v = tau[:, j][np.isfinite(tau[:, j])]
        if len(v) < 100:
            continue
        u = np.unique(v)
        if len(u) > 0.98 * len(v) or len(u) < 2:
            continue
        d = np.diff(u)
        d = d[d > 1e-9 * max(float(np.max(np.abs(u))), 1e-300)]
        if not len(d):
            continue
        q = float(d.min())
        x = v / q
        if np.mean(np.abs(x - np.round(x)) < 0.02) >= GRID_SHARE:
            out[j] = q
    return out


def hold_at_rest(applied: np.ndarray, friction: np.ndarray, velocity: np.ndarray, v_rest: np.ndarray,
                 f_static: np.ndarray) -> np.ndarray:
    """The model's friction with its breakaway level (eq. 2-3): where a motor is at rest (|velocity| below
    ``v_rest``) friction holds whatever torque the rest of the model leaves (``applied``: measured torque minus the
    rigid-body, inertia and offset parts), up to f_s (:func:`js2spec.model.friction_hold_limit`: no limit where f_s
    was not identified); elsewhere ``friction`` (B v + f_c sgn v). Arrays (N, n), one side, SI. Rows at rest are
    never scored, but the torque filter spreads them into the slow rows next to them: a sliding law there smears a
    friction the arm did not have (the excess looked like a Stribeck curve on clean recordings)."""
    limit = friction_hold_limit(f_static)
    rest = at_rest(velocity, v_rest[None, :])
    held = np.clip(np.nan_to_num(applied), -limit[None, :], limit[None, :])
    return np.where(rest & np.isfinite(applied), held, friction)


def residual_data(model: IdentifiedModel, log, *, holdout_trial: str = "validation", fit_trials=None,
                  min_speed: float = 0.01, settings: FilterSettings | None = None,
                  report_fraction: float = 0.3) -> ResidualData:
    """Predict the recording with the model, on the motor side, and split it into fit, select and report rows
    (:func:`split_rows`). ``min_speed``: rad/s at the joint; motor i's threshold is min_speed / max_j |K_ji|."""
    drives = log.drives
    side = str(drives.torque_side)
    problem = model.recording_mismatch(drives)
    if problem is not None:
        what, text = problem
        advice = ("diagnose a recording of the arm the model describes" if what == "joints" else
                  f"identify the model from recordings with {side}-side torques")
        raise DiagnosisError(f"{log.path}: {text} ({model.path}); {advice}")
    arm = arm_model(model.urdf_text, drives, urdf_name=str(model.urdf_path))
    sig = from_log(log, settings or model_cutoffs(float(log.cycle_hz), model))
    N, n = sig.q_motor.shape
    K = np.asarray(drives.gear_ratio_matrix, float)
    good = np.all(np.isfinite(sig.q_motor), axis=1) & np.all(np.isfinite(sig.tau), axis=1)
    rows = np.flatnonzero(good)
    # the prediction is filtered like the torque below (parallel filtering), so it is made from the acceleration
    # before that filter, as identification's regressor is (Signals.acceleration_unfiltered)
    ddq_motor = sig.acceleration_unfiltered()
    qm, dqm, ddqm = sig.q_motor[rows], sig.dq_motor[rows], ddq_motor[rows]
    # the regressor on every row (on the log's torque side), a bad row's zero: its rigid-body block is then the
    # search's W_rigid_motor as it is, with no copy of its 10 n columns (about 1 CPU s of a 5-minute, 500 Hz
    # session, most of it fresh pages); each row is made on its own, so a good row's numbers are as on the good
    # rows alone
    if len(rows) == N:
        W = build_regressor(arm, qm, dqm, ddqm)
    else:
        W = build_regressor(arm, *(np.where(good[:, None], x, 0.0) for x in (sig.q_motor, sig.dq_motor, ddq_motor)))
        W[~good] = 0.0
    pi = standard_vector(arm, motor_inertia=model.motor_inertia, viscous=model.friction_viscous,
                         coulomb=model.friction_coulomb)
    nl = 10 * n
    off = model.torque_offset             # the exported model's (IdentifiedModel.torque_offset)
    if side == "joint":
        W[:, :, :nl] = np.matmul(K.T, W[:, :, :nl])    # the rigid-body part to the motor side (K^T Y)

    def to_motor(x):                                   # (N, n) on the log's side -> motor side: K^T x, row-wise
        return x @ K if side == "joint" else x

    pred_side = np.full((N, n), np.nan)
    fric_side = np.full((N, n), np.nan)
    # the model's friction on the log's side: B v + f_c sgn v (+ Bs sgn(v) sqrt|v| when identification kept it)
    v_side = dqm @ K.T if side == "joint" else dqm
    fsq = model.friction_sqrt_viscous if model.friction_sqrt_viscous is not None else np.zeros(n)
    sqrt_term = fsq * np.sign(v_side) * np.sqrt(np.abs(v_side))
    pred_side[rows] = np.einsum("snp,p->sn", W[:, :, nl:], pi[nl:])[rows] + off + sqrt_term
    fric_side[rows] = np.einsum("snp,p->sn", W[:, :, 11 * n:], pi[11 * n:])[rows] + sqrt_term
    W_rigid = W[:, :, :nl]                  # a view: zero on the bad rows
    del W
    rigid_motor = np.full((N, n), np.nan)
    rigid_motor[rows] = (W_rigid @ pi[:nl])[rows]
    rigid_joint = np.full((N, n), np.nan)
    rigid_joint[rows] = rigid_motor[rows] @ np.linalg.inv(K)        # tau_joint = K^-T tau_motor
    # motor i's rest speed: min_speed at the joint, carried to the motor (js2spec.drives, the rule hil_sim's replay
    # holds by too); ``mask`` drops the rows below it
    v_motor = motor_rest_speed(min_speed, K)
    rest = at_rest(sig.dq_motor, v_motor[None, :])
    # at rest the model's friction holds the applied torque, up to f_s (eq. 2-3), instead of B v + f_c sgn v
    rigid_side = rigid_joint[rows] if side == "joint" else rigid_motor[rows]
    v_rest = np.full(n, float(min_speed)) if side == "joint" else v_motor
    held = hold_at_rest(sig.tau_raw[rows] - rigid_side - (pred_side[rows] - fric_side[rows]), fric_side[rows],
                        v_side, v_rest, model.friction_static)
    pred_side[rows] += held - fric_side[rows]
    fric_side[rows] = held
    tau_pred = to_motor(pred_side)
    tau_pred[rows] += rigid_motor[rows]
    friction = to_motor(fric_side)
    # parallel filtering: the prediction passes the torque's filter too
    tau_pred_f = np.full((N, n), np.nan)
    tau_pred_f[rows] = sig.filter_like_torque(np.nan_to_num(tau_pred))[rows]
    tau_meas, tau_meas_raw = to_motor(sig.tau), to_motor(sig.tau_raw)
    kt = np.asarray(drives.torque_constant, float)
    current = tau_meas_raw / np.where(kt > 0, kt, 1.0)

    t = sig.t - sig.t[0]
    keep = sig.keep & good
    mask = keep[:, None] & ~rest
    fit, sel, hold, note = split_rows(log, sig.t, keep, holdout_trial, fit_trials, report_fraction, moving=mask)
    counts = {name: int((mask & rr).any(axis=1).sum()) for name, rr in
              (("fit", fit), ("select", sel), ("report", hold))}
    if min(counts.values()) < 20:
        raise DiagnosisError(f"{log.path}: not enough moving samples to fit, select and report (rows "
                             + ", ".join(f"{k} {v}" for k, v in counts.items())
                             + f" faster than {min_speed:g} rad/s at a joint); record a longer motion, or lower "
                               "--min-speed")
    return ResidualData(log_path=str(log.path), t=t, fs=sig.fs, q_motor=sig.q_motor, dq_motor=sig.dq_motor,
                        ddq_motor=ddq_motor, q_joint=arm.joint_from_motor(sig.q_motor), tau_meas=tau_meas,
                        tau_meas_raw=tau_meas_raw, tau_pred=tau_pred_f, tau_pred_raw=tau_pred,
                        W_rigid_motor=W_rigid, tau_rigid_joint=rigid_joint,
                        tau_rigid_motor=rigid_motor, friction_pred=friction, motor_current=current, mask=mask,
                        fit_rows=fit, holdout_rows=hold, K=K, joints=list(drives.joints), arm=arm, signals=sig,
                        split_note=note, extra={"model": model, "min_speed": min_speed},
                        select_rows=sel, min_speed_motor=v_motor, torque_side=side,
                        torque_step_motor=torque_step(drives, tau_meas_raw),
                        at_rest=rest)


@dataclass
class OwnOffsets:
    """The constant torque per motor (N*m, motor side) the model leaves on the recordings it was identified from:
    the mean of the residual over their moving rows (``offset``, (n,)) and that mean's standard error from the
    spread of its one-second block means (``std``, (n,)); ``names``: the recordings'."""
    offset: np.ndarray
    std: np.ndarray
    names: list


def own_recordings(model: IdentifiedModel, min_speed: float = 0.01) -> list[tuple[str, "ResidualData"]]:
    """The model's fitted ``inputs`` (model.yaml; validation recordings left out) that can still be read where they
    were (the path as written, else beside model.yaml) and are unchanged (sha256, or the data's), each as (file name,
    its :class:`ResidualData` against the model); empty when none can. What the model leaves on the recordings it was
    identified from is its own structure: a reading a new recording shares with them is not physics the new one
    adds (:func:`own_offsets`, :meth:`diagnosis.library.Coupling.own_reading`)."""
    out = []
    base = Path(model.path).parent if model.path else Path(".")
    for item in model.inputs:
        if item.get("role") == "validation" or not item.get("path"):
            continue
        p = Path(str(item["path"]))
        p = p if p.is_file() else base / p.name
        if not p.is_file():
            continue
        try:
            lg = read_log(p)
            if not model.is_recording(item, lg):
                continue
            out.append((p.name, residual_data(model, lg, min_speed=min_speed)))
        except (Js2Error, OSError, ValueError):
            continue
    return out


def extra_once(rd: "ResidualData", key: str):
    """``rd.extra[key]``, made on first use where it is kept as a callable (None when absent, or ``rd`` has no
    ``extra``)."""
    value = getattr(rd, "extra", {}).get(key)
    if callable(value):
        value = rd.extra[key] = value()
    return value


def own_offsets(model: IdentifiedModel, min_speed: float = 0.01, block_s: float = 1.0,
                recordings: list | None = None) -> OwnOffsets | None:
    """:class:`OwnOffsets` of the model's own recordings (:func:`own_recordings`, or ``recordings`` as it returns
    them); None when none can be read. A constant a new recording carries that the model's own recording carries
    too is the model's structure (js2-identify leaves offsets out by cross-validation), not physics the new one
    adds."""
    recordings = own_recordings(model, min_speed) if recordings is None else recordings
    parts = [(rd.residual, rd.mask, rd.t) for _, rd in recordings]
    names = [name for name, _ in recordings]
    if not parts:
        return None
    n = parts[0][0].shape[1]
    offset, std = np.full(n, np.nan), np.full(n, np.nan)
    for j in range(n):
        vals, blocks = [], []
        for r, m, t in parts:
            v, b = r[m[:, j], j], np.floor(t[m[:, j]] / block_s).astype(int)
            if len(v):
                vals.append(v)
                cnt = np.bincount(b - b.min())
                blocks.append((np.bincount(b - b.min(), weights=v))[cnt > 0] / cnt[cnt > 0])
        if not vals:
            continue
        offset[j] = float(np.mean(np.concatenate(vals)))
        blocks = np.concatenate(blocks)
        std[j] = float(np.std(blocks) / np.sqrt(len(blocks))) if len(blocks) > 1 else float("inf")
    return OwnOffsets(offset=offset, std=std, names=names)
