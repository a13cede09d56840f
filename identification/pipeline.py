"""From js2 logs to the model: the compound (mixed) and simultaneous methods end to end.

``identify(paths, options) -> Identification``; the CLI (``js2-identify``) only parses arguments, calls this and the
writers in :mod:`identification.output`. Steps (the paper's, numbered as in ``docs/identification.md``):

1. read the logs (``js2spec.log.read_log``), check they describe the same arm, build the model (URDF + K);
2. signals: K mapping, zero-phase filters (the paper's 50 Hz velocity, 7 Hz acceleration and torque, or what
   ``signals.choose_cutoffs`` allows at the log's rate), lost cycles, trims; method and fit trial from the log;
3. sequential part: static test (eq. 2-4) -> f_s and gravity at the poses; constant velocity (eq. 5) -> B, f_c;
4. regressor of eq. 1 on the acceleration trial, base parameters (pivoted QR), condition number;
5. mixed method: friction fixed, RLS over the acceleration trial (35,000 iterations or all samples);
   simultaneous method: the same RLS with the friction columns free; batch OLS/WLS for both;
6. physically consistent standard parameters fitted to the base parameters (J_a, fitted B, f_c >= 0; prior weight
   toward the URDF by cross-validation on the fit data): the exported model;
7. validation on data not used for fitting (a ``validation`` trial, ``--validate`` logs, or a held-out tail), beside
   the textbook OLS baseline fitted on the same samples.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from js2spec.errors import ConfigError, Js2Error, LogError
from js2spec.log import read_log

from . import signals as sg
from .base import BaseParameters, base_parameters, condition_number, friction_mask
from .consistency import PhysicalConsistencyFit
from .estimators import BatchLeastSquares, RecursiveLeastSquares
from .regressor import ArmModel, arm_model, build_regressor, column_groups
from .sequential import ConstantVelocityTest, StaticFrictionTest
from .trials import TrialSpan, breakaways, trial_spans, velocity_segments


class IdentificationError(Js2Error):
    """The input cannot be identified as asked (a trial missing, too little data, ...); names the file."""


@dataclass
class IdentifyOptions:
    method: str = "auto"                     # mixed | simultaneous | auto (mixed when the log has static and
                                             # velocity trials, else simultaneous): the model written out
    filters: sg.FilterSettings | None = None  # None: chosen from the sample rate and motion (sg.choose_cutoffs)
    n_iter: int | None = 35000               # RLS iterations (samples); None = all
    fit_trials: tuple | None = None          # trials whose samples feed the inertial fit; None: 'acceleration' if
                                             # present, else 'excitation', else every sample ('all')
    validation_trials: tuple = ("validation",)
    holdout: float = 0.25                    # tail fraction held out when no validation data exists
    sqrt_viscous: bool | None = None         # Bs sgn(v) sqrt|v| friction per axis; None: tried by the simultaneous
                                             # method, kept if 3-fold CV on the fit data prefers it
    offsets: bool | None = None              # constant torque offset per axis (off_k): sensor/current bias; None:
                                             # tried by the simultaneous method, kept if CV on the fit data prefers
    v_min_fraction: float = 0.03             # rows with |motor speed| below this fraction of the axis's p99 speed
                                             # are left out of the dynamic fit (stiction zone, eq. 1 has sgn only)
    fig3: tuple = ("J_4z", "B_4", "fc_4")    # parameters whose RLS convergence is plotted (Fig. 3)
    physical: bool = True
    prior_weight: float | None = None        # pull of the URDF in the physically consistent fit (see consistency.py);
                                             # None: 1 for the mixed method, chosen by cross-validation on the fit
                                             # data for the simultaneous method
    progress: bool = False
    validate_paths: tuple = ()               # extra held-out logs


@dataclass
class MethodResult:
    name: str                                # "mixed" or "simultaneous"
    free: np.ndarray                         # indices (into base parameters) estimated by the RLS
    beta: np.ndarray                         # all base parameter values (fixed ones included)
    std: np.ndarray
    rls: RecursiveLeastSquares
    ols: BatchLeastSquares
    wls: BatchLeastSquares
    history: np.ndarray                      # (checkpoints, n_base) full base vector at each checkpoint
    history_iter: np.ndarray


@dataclass
class Identification:
    options: IdentifyOptions
    arm: ArmModel
    bp: BaseParameters
    logs: list
    inputs: list[dict]
    notes: list[str]
    static: StaticFrictionTest | None
    velocity: ConstantVelocityTest | None
    friction_static: np.ndarray
    friction_static_std: np.ndarray
    friction_coulomb: np.ndarray
    friction_coulomb_std: np.ndarray
    friction_viscous: np.ndarray
    friction_viscous_std: np.ndarray
    methods: dict[str, MethodResult]
    chosen: str
    condition_number: float
    condition_number_raw: float
    n_fit_samples: int
    validation: dict
    physical: PhysicalConsistencyFit | None
    fit_data: dict = field(default_factory=dict)
    val_data: dict = field(default_factory=dict)
    static_per_direction: dict | None = None   # motor -> {"+": f_s+, "-": f_s-, "+_std", "-_std"}
    friction_sqrt_viscous: np.ndarray | None = None   # Bs per axis (NaN: not in the model)

    @property
    def model(self) -> MethodResult:
        return self.methods[self.chosen]

    def motor_inertia(self) -> tuple[np.ndarray, np.ndarray, list[bool]]:
        """Per-motor J_a (kg m^2), std and whether it is identified separately (not regrouped)."""
        n = self.arm.n
        ja, sd, alone = np.full(n, np.nan), np.full(n, np.nan), []
        for k in range(n):
            name = f"Ja_{k + 1}"
            a = self.bp.is_alone(name)
            alone.append(a)
            i = self.bp.index_of(name)
            if a:
                ja[k], sd[k] = self.model.beta[i], self.model.std[i]
            if self.physical is not None:      # the exported model's value (>= 0)
                ja[k] = self.physical.motor_inertia_[k]
        return ja, sd, alone

    def param_index(self, alias: str) -> int:
        return resolve_parameter(self.arm, self.bp, alias)


def resolve_parameter(arm: ArmModel, bp: BaseParameters, alias: str) -> int:
    """Base-parameter index of a name: a standard name (``Ixx_link4``, ``Ja_2``, ``B_4``, ``fc_4``) or the paper's
    ``J_<i>z`` (link i's inertia about its own joint axis), 1-based axis numbers."""
    a = alias.strip()
    if a.upper().startswith("J_") and a.lower().endswith("z") and a[2:-1].isdigit():
        std = arm.axis_inertia_name(int(a[2:-1]) - 1)
    else:
        std = a
    if std not in bp.std_names:
        raise IdentificationError(f"unknown parameter {alias!r}: use a standard name such as "
                                  f"{bp.std_names[0]!r}, 'Ja_1', 'B_1', 'fc_1' or the paper's 'J_4z'")
    i = bp.index_of(std)
    if i is None:
        raise IdentificationError(f"parameter {alias!r} ({std}) has no effect on the torques (not identifiable)")
    return i


# ----------------------------------------------------------------------------------------------------------------

def _progress(enabled: bool, desc: str):
    if not enabled:
        return None
    from tqdm import tqdm

    return lambda it: tqdm(it, desc=desc, leave=False, mininterval=0.3, disable=None)   # None: terminals only


def load_logs(paths) -> list:
    """Read the logs (``read_log``); items that are already ``Js2Log`` objects are used as they are."""
    logs = []
    for p in paths:
        log = p if hasattr(p, "feedback") and hasattr(p, "drives") else read_log(p)
        logs.append(log)
    return logs


def n_of(log) -> int:
    return log.drives.n


def check_same_arm(logs) -> None:
    ref = logs[0]
    for lg in logs[1:]:
        if list(lg.drives.joints) != list(ref.drives.joints) or not np.allclose(
                lg.drives.gear_ratio_matrix, ref.drives.gear_ratio_matrix):
            raise LogError(lg.path, f"describes a different arm (joints or gear ratios) than {ref.path}")
        if lg.drives.torque_side != ref.drives.torque_side:
            raise LogError(lg.path, f"torque_side '{lg.drives.torque_side}' differs from {ref.path}")


def _arm_from_log(log) -> ArmModel:
    try:
        return arm_model(log.urdf_text, log.drives, urdf_name=f"{log.path}:robot.urdf")
    except ConfigError as exc:
        raise LogError(log.path, f"attachment robot.urdf: {exc.problem}") from None


def _span_index(sig, t0, t1):
    return np.flatnonzero(sig.mask_between(t0, t1))


def _regressor_rows(arm, bp, sig, idx, offsets, progress=None, sqrt_viscous=False):
    """Filtered base regressor (len(idx), n, r) and filtered torque at sample indices ``idx`` of ``sig``.

    The regressor is built from the 50 Hz signals (q, dq, d/dt dq) over the whole contiguous stretches that contain
    ``idx`` (plus the filter's margin), projected on the base columns, then passed through the torque's 7 Hz filter
    (parallel filtering), so regressor and torque have seen the same filter."""
    if len(idx) == 0:
        return np.zeros((0, arm.n, bp.n)), np.zeros((0, arm.n)), np.zeros((0, arm.n))
    fs = sig.fs
    margin = int(round(3 * sig.settings.trim * fs))
    out_W = np.empty((len(idx), arm.n, bp.n))
    out_v = np.empty((len(idx), arm.n))
    for a, b in sig.runs:
        inside = idx[(idx >= a) & (idx < b)]
        if len(inside) == 0:
            continue
        lo, hi = max(a, int(inside[0]) - margin), min(b, int(inside[-1]) + margin + 1)
        q = sig.q_motor[lo:hi]
        dq = sig.dq_motor[lo:hi]
        ddq = np.gradient(dq, 1.0 / fs, axis=0)
        # built in chunks and projected on the base columns at once: memory ~ N x n x n_base, not N x n x n_std
        Wb = np.empty((hi - lo, arm.n, bp.n))
        step = 1024
        chunks = range(0, hi - lo, step)
        for c0 in (progress(chunks) if progress is not None else chunks):
            c1 = min(c0 + step, hi - lo)
            Wb[c0:c1] = bp.project(build_regressor(arm, q[c0:c1], dq[c0:c1], ddq[c0:c1], offsets=offsets,
                                                   sqrt_viscous=sqrt_viscous,
                                                   velocity_for_sign=None))
        # the torque's filter on every column (parallel filtering), a block of columns at a time (memory)
        flat = Wb.reshape(len(Wb), -1)
        for k0 in range(0, flat.shape[1], 48):
            flat[:, k0:k0 + 48] = sg._lp_runs(flat[:, k0:k0 + 48], sig.settings.fc_acceleration_hz, fs,
                                              sig.settings.order, [(0, hi - lo)])
        Wf = Wb
        rel = inside - lo
        where = np.searchsorted(idx, inside)
        out_W[where] = Wf[rel]
        out_v[where] = dq[rel]
    return out_W, sig.tau[idx], out_v


def _row_weights(v, frac):
    """Exclude rows (axis k at sample s) whose motor speed is in the stiction zone: |v| < frac * p99(|v_k|)."""
    p99 = np.percentile(np.abs(v), 99, axis=0)
    return (np.abs(v) >= frac * np.maximum(p99, 1e-12)).astype(float)


def resolve_filters(logs, given: sg.FilterSettings | None) -> sg.FilterSettings:
    """The filter settings used: ``given`` (checked against each log's Nyquist frequency), else
    :func:`identification.signals.choose_cutoffs` from the lowest sample rate and the widest motion bandwidth."""
    fs = min(float(lg.cycle_hz) for lg in logs)
    if given is not None:
        for lg in logs:
            nyq = float(lg.cycle_hz) / 2
            for name, v in (("velocity", given.fc_velocity_hz), ("acceleration", given.fc_acceleration_hz)):
                if v is not None and not 0 < v < nyq:
                    raise IdentificationError(
                        f"{lg.path}: {name} filter cut-off {v:g} Hz must lie between 0 and the Nyquist frequency "
                        f"{nyq:g} Hz of this {float(lg.cycle_hz):g} Hz log; give a lower one or leave it out "
                        f"(then chosen from the data)")
        if given.fc_velocity_hz is not None and given.fc_acceleration_hz is not None:
            return given
    bw = max(sg.motion_bandwidth(lg.feedback.motor_position, float(lg.cycle_hz)) for lg in logs)
    if given is None:
        return sg.choose_cutoffs(fs, bw)
    ch = sg.choose_cutoffs(fs, bw, given.fc_velocity_hz, given.fc_acceleration_hz, given.order)
    return replace(given, fc_velocity_hz=ch.fc_velocity_hz, fc_acceleration_hz=ch.fc_acceleration_hz, reason=ch.reason)


def identify(paths, options: IdentifyOptions | None = None, _notes=()) -> Identification:
    opt = options or IdentifyOptions()
    paths = [p if hasattr(p, "feedback") else Path(p) for p in paths]
    if not paths:
        raise IdentificationError("no log given")
    notes: list[str] = []
    logs = load_logs(paths)
    post_notes = list(_notes)
    check_same_arm(logs)
    arm = _arm_from_log(logs[0])
    n = arm.n
    inputs = []
    for lg in logs:
        inputs.append({"path": str(lg.path), "sha256": lg.sha256, "data_sha256": lg.data_sha256, "source": lg.source,
                       "truncated": bool(lg.truncated), "trials": lg.trials()})
        if lg.recovered_note:        # truncated, corrupt mid-file, or repaired
            notes.append(f"{lg.path}: {lg.recovered_note}; identified from what was recovered")
        for w in lg.warnings:
            notes.append(f"{lg.path}: {w}")
        bad = ~np.isfinite(lg.feedback.torque) | ~np.isfinite(lg.feedback.motor_position)
        frac = bad.mean(axis=0) if len(bad) else np.zeros(n_of(lg))
        worst = int(np.argmax(frac)) if len(frac) else 0
        if len(frac) and frac[worst] > 0.5:
            raise IdentificationError(
                f"{lg.path}: {100 * frac[worst]:.0f} % of the torque/position samples of axis "
                f"{lg.drives.joints[worst]} are NaN or infinite: nothing to identify that axis from")
        if bad.any():
            notes.append(f"{lg.path}: {int(bad.any(axis=1).sum())} cycles with NaN/inf values excluded "
                         f"(treated as lost cycles, not interpolated)")
    prog = opt.progress
    # 2. signals per log, through filters chosen from the sample rate and the motion unless given
    opt = replace(opt, filters=resolve_filters(logs, opt.filters))
    notes.append(f"filters: {opt.filters.reason}")
    sigs = []
    for lg in logs:
        sig = sg.from_log(lg, opt.filters)
        if sig.note != "no lost or invalid cycles":
            notes.append(f"{lg.path}: {sig.note}")
        sigs.append(sig)
    spans = {}
    for i, (lg, sig) in enumerate(zip(logs, sigs)):
        for sp in trial_spans(lg.events, float(lg.feedback.t[-1]), i):
            spans.setdefault(sp.name, []).append(sp)
        # "all": every sample of every log (logs without trial events; --fit-trials all)
        spans.setdefault("all", []).append(TrialSpan("all", float(sig.t[0]), float(sig.t[-1]), i))
    # 3. sequential part
    static = velocity = None
    fs_ = np.full(n, np.nan)
    fs_sd = np.full(n, np.nan)
    if "static" in spans:
        recs = []
        for sp in spans["static"]:
            recs += breakaways(logs[sp.log_index], sigs[sp.log_index], "static")
        if recs:
            static = StaticFrictionTest(n).fit(recs)
            fs_, fs_sd = static.static_, static.static_std_
            for r in static.rejected_:
                where = f"t = {r.t:.3f} s" if r.direction else "pose"
                notes.append(f"static test: motor {r.motor + 1} at pose {list(r.pose)} ({where}) left out of eq. 3: "
                             f"{r.rejected}")
            nb = sum(r.from_event for r in recs)
            if nb < len(recs):
                notes.append(f"static test: {len(recs) - nb} of {len(recs)} breakaways detected from the data "
                             f"(no breakaway event in those ramps)")
    fc_ = np.full(n, np.nan)
    fc_sd = np.full(n, np.nan)
    fv_ = np.full(n, np.nan)
    fv_sd = np.full(n, np.nan)
    if "velocity" in spans:
        segs_all = []
        for li in sorted({sp.log_index for sp in spans["velocity"]}):
            segs_all += velocity_segments(logs[li], sigs[li], "velocity")   # each segment knows its log's signals
        if segs_all:
            velocity = ConstantVelocityTest(n).fit(arm, None, segs_all,
                                                   balance=static.gravity_ if static is not None else None)
            fc_, fc_sd = velocity.coulomb_, velocity.coulomb_std_
            fv_, fv_sd = velocity.viscous_, velocity.viscous_std_
    if opt.method == "auto":
        if "velocity" in spans and np.all(np.isfinite(fc_)) and np.all(np.isfinite(fv_)):
            opt = replace(opt, method="mixed")
        else:
            have = sorted(k for k in spans if k != "all") or ["none"]
            why = ("the 'velocity' trial has no usable steady segment on every axis" if "velocity" in spans else
                   f"no friction trials in the input, trials: {', '.join(have)}")
            opt = replace(opt, method="simultaneous")
            notes.append(f"method: simultaneous ({why}); friction identified with the inertial parameters")
    if opt.fit_trials is None:
        pick = next((t for t in ("acceleration", "excitation") if t in spans), "all")
        opt = replace(opt, fit_trials=(pick,))
        if pick != "acceleration":
            notes.append(f"fit data: the {pick!r} trial" if pick != "all" else
                         "fit data: every sample (no 'acceleration' or 'excitation' trial in the input)")
    # the square-root viscous term: tried by the simultaneous method, kept when cross-validation on the fit data says
    sqv = opt.sqrt_viscous if opt.sqrt_viscous is not None else opt.method == "simultaneous"
    tried = {"sqrt_viscous": opt.sqrt_viscous is None and sqv,
             "offsets": opt.offsets is None and opt.method == "simultaneous"}
    opt = replace(opt, offsets=bool(opt.offsets) if opt.offsets is not None else opt.method == "simultaneous")
    bp = base_parameters(arm, offsets=opt.offsets, sqrt_viscous=sqv)
    groups = column_groups(arm, opt.offsets, sqv)
    fmask = friction_mask(bp, arm, opt.offsets, sqv)
    if opt.method == "mixed":
        missing = [k + 1 for k in range(n) if not (np.isfinite(fc_[k]) and np.isfinite(fv_[k]))]
        if "velocity" not in spans:
            raise IdentificationError(
                f"{', '.join(str(getattr(p, 'path', p)) for p in paths)}: no 'velocity' trial (constant-velocity test, eq. 5) in the input; the "
                f"mixed method needs it for B and f_c. Record it (js2-acquire --trial velocity) or use "
                f"--method simultaneous")
        if missing:
            raise IdentificationError(
                f"{', '.join(str(getattr(p, 'path', p)) for p in paths)}: the 'velocity' trial has no usable steady segment for axis/axes "
                f"{missing}; the mixed method needs B and f_c of every axis (or use --method simultaneous)")
    # 4. fitting data
    fit_names = [t for t in opt.fit_trials if t in spans]
    if not fit_names:
        have = sorted(k for k in spans if k != "all") or ["none"]
        raise IdentificationError(
            f"{', '.join(str(getattr(p, 'path', p)) for p in paths)}: no {' or '.join(repr(t) for t in opt.fit_trials)} trial for the inertial "
            f"fit (trials present: {', '.join(have)}); pass --fit-trials with one that is there, or 'all'")
    fitW, fitY, fitV = [], [], []
    val_parts = []
    fit_where, val_where = [], []   # (Signals, sample indices): lets other models be evaluated on the same samples
    for name in fit_names:
        for sp in spans[name]:
            sig = sigs[sp.log_index]
            idx = _span_index(sig, sp.t0, sp.t1)
            W, y, v = _regressor_rows(arm, bp, sig, idx, opt.offsets, _progress(prog, f"regressor {name}"), sqv)
            fitW.append(W), fitY.append(y), fitV.append(v)
            fit_where.append((sig, idx))
    W = np.concatenate(fitW)
    Y = np.concatenate(fitY)
    V = np.concatenate(fitV)
    # validation data
    vnames = [t for t in opt.validation_trials if t in spans]
    for name in vnames:
        for sp in spans[name]:
            sig = sigs[sp.log_index]
            idx = _span_index(sig, sp.t0, sp.t1)
            val_parts.append(_regressor_rows(arm, bp, sig, idx, opt.offsets, None, sqv)
                             + (f"{logs[sp.log_index].path}:{name}",))
            val_where.append((sig, idx))
    for vp in opt.validate_paths:
        vlog = read_log(vp)
        check_same_arm([logs[0], vlog])
        vsig = sg.from_log(vlog, opt.filters)
        vsp = trial_spans(vlog.events, float(vlog.feedback.t[-1]))
        chosen = [s for s in vsp if s.name in opt.validation_trials + opt.fit_trials] or \
            [type("S", (), {"t0": float(vlog.feedback.t[0]), "t1": float(vlog.feedback.t[-1]), "name": "all"})()]
        inputs.append({"path": str(vlog.path), "sha256": vlog.sha256, "source": vlog.source,
                       "truncated": bool(vlog.truncated), "trials": vlog.trials(), "role": "validation"})
        for s in chosen:
            idx = _span_index(vsig, s.t0, s.t1)
            val_parts.append(_regressor_rows(arm, bp, vsig, idx, opt.offsets, None, sqv) + (f"{vlog.path}:{s.name}",))
            val_where.append((vsig, idx))
    if not val_parts:
        k = int(round(len(W) * (1 - opt.holdout)))
        if k < 10 or len(W) - k < 10:
            raise IdentificationError(f"{logs[0].path}: too few samples ({len(W)}) to hold out a validation part")
        val_parts.append((W[k:], Y[k:], V[k:], f"last {opt.holdout:.0%} of the fit trial(s) (held out)"))
        W, Y, V = W[:k], Y[:k], V[:k]
        allw = [(sg_, ix) for sg_, ix in fit_where]
        sizes = np.cumsum([len(ix) for _, ix in allw])
        fit_where, val_where = [], []
        start = 0
        for (sg_, ix), end in zip(allw, sizes):
            cut = min(max(k - start, 0), len(ix))
            if cut > 0:
                fit_where.append((sg_, ix[:cut]))
            if cut < len(ix):
                val_where.append((sg_, ix[cut:]))
            start = end
        notes.append(f"no validation trial: the last {opt.holdout:.0%} of the fitting data was held out for validation")
    if len(W) < 2 * bp.n:
        raise IdentificationError(f"{logs[0].path}: only {len(W)} usable samples in the fit trial(s)")
    wts = _row_weights(V, opt.v_min_fraction)
    decided, retry_notes = {}, []
    for term, prefix, label in (("offsets", "off_", "constant torque offsets"),
                                ("sqrt_viscous", "Bs_", "square-root viscous friction")):
        if tried[term]:
            keep, cv_txt = _term_cross_validation(W, Y, wts, bp, prefix)
            decided[term] = keep
            (notes if keep else retry_notes).append(f"{label} {'kept' if keep else 'left out'}: {cv_txt}")
    if retry_notes:
        return identify(paths, replace(options or IdentifyOptions(), **decided),
                        _notes=[nt for nt in notes if nt.startswith(("constant torque", "square-root"))] + retry_notes)
    cond = condition_number(W)
    cond_raw = condition_number(W, normalise=False)
    # 5. estimators
    methods = {}
    nfr = np.flatnonzero(~fmask)
    fr = np.flatnonzero(fmask)
    friction_seq = np.full(bp.n, np.nan)
    for i in fr:
        lead = bp.lead(i)
        kind, k = lead.split("_")
        k = int(k) - 1
        friction_seq[i] = {"B": fv_, "fc": fc_}.get(kind, np.full(n, 0.0))[k]
    run_mixed = np.all(np.isfinite(friction_seq[fr])) if len(fr) else True
    if opt.method == "mixed" and not run_mixed:
        raise IdentificationError(f"{logs[0].path}: friction of some axes missing from the sequential tests")
    todo = (["mixed"] if run_mixed and np.isfinite(fv_).all() else []) + ["simultaneous"]
    for name in todo:
        if name == "mixed":
            # friction fixed from the sequential tests (eq. 5); offsets (if modelled) are not measured there: free
            off_idx = [i for i in fr if bp.lead(i).startswith("off_")]
            free = np.sort(np.concatenate([nfr, off_idx])).astype(int)
            fixed_idx = np.array([i for i in fr if i not in off_idx], int)
            y = Y - np.einsum("smp,p->sm", W[:, :, fixed_idx], friction_seq[fixed_idx])
        else:
            free = np.arange(bp.n)
            fixed_idx = np.array([], int)
            y = Y
        H = W if len(free) == bp.n else W[:, :, free]
        corr = sigs[0].fs / (2 * opt.filters.fc_acceleration_hz)
        rls = RecursiveLeastSquares(n_iter=opt.n_iter, correlation_length=corr).fit(
            H, y, wts, progress=_progress(prog, f"RLS {name}"))
        ols = BatchLeastSquares("ols", corr).fit(H, y, wts)
        wls = BatchLeastSquares("wls", corr).fit(H, y, wts)
        beta = np.zeros(bp.n)
        std = np.zeros(bp.n)
        beta[free] = rls.coef_
        std[free] = rls.std_
        if len(fixed_idx):
            beta[fixed_idx] = friction_seq[fixed_idx]
            for i in fixed_idx:
                kind, k = bp.lead(i).split("_")
                std[i] = {"B": fv_sd, "fc": fc_sd}[kind][int(k) - 1]
        hist = np.tile(beta, (len(rls.history_), 1))
        hist[:, free] = rls.history_
        methods[name] = MethodResult(name, free, beta, std, rls, ols, wls, hist, rls.history_iter_)
    chosen = opt.method if opt.method in methods else "simultaneous"
    if chosen != opt.method:
        notes.append(f"method {opt.method} not possible on this input; {chosen} used")
    # 6. physically consistent model
    phys = None
    if opt.physical:
        mr = methods[chosen]
        # information of the data, with the same correction for filtered (correlated) rows as the standard errors
        corr = sigs[0].fs / (2 * opt.filters.fc_acceleration_hz)
        scale = max(mr.rls.sigma2_ * corr, 1e-30)
        p = len(bp.std_names)
        fixed_std = np.full(p, np.nan)
        nonneg = []
        # friction measured by the sequential tests (mixed) stays as measured; fitted friction (simultaneous) is
        # refitted here with B >= 0 and f_c >= 0; offsets are free
        for i in fr:
            lead = bp.lead(i)
            j = bp.std_names.index(lead)
            if lead.startswith("off_"):
                continue
            if lead.startswith("Bs_") and chosen == "mixed":
                fixed_std[j] = 0.0
                continue
            if lead.startswith("Bs_"):
                nonneg.append(j)
                continue
            if chosen == "mixed":
                fixed_std[j] = mr.beta[i]
            else:
                nonneg.append(j)
        fit_args = (bp, arm, groups["motor"], fixed_std, nonneg, scale)
        try:
            weight, cv = opt.prior_weight, None
            if weight is None and chosen == "mixed":
                weight = 1.0      # friction measured by the paper's tests: the inertial fit is well posed; the
                                  # cross-validation (18 extra fits) is kept for the simultaneous method
            if weight is None:
                weight, cv = cross_validated_prior_weight(W, Y, wts, mr, *fit_args)
                notes.append(f"prior weight toward the URDF: {weight:g}, chosen by {len(cv['folds'])}-fold "
                             f"cross-validation on the fit data (held-out torque error "
                             + ", ".join(f"{w:g}: {100 * e:.2f} %" for w, e in zip(cv["weights"], cv["rel_error"]))
                             + ")")
            phys = _physical_fit(W, Y, wts, mr, weight, *fit_args)
            phys.prior_weight_cv_ = cv
        except np.linalg.LinAlgError as exc:
            notes.append(f"physically consistent fit failed ({exc})")
    # static friction per direction: with the identified gravity at each static pose (eq. 2 with G known),
    # f_s+ = tau+ - G and f_s- = G - tau-; eq. 3 alone gives only their mean
    static_dir = None
    if static is not None and static.gravity_:
        static_dir = static_per_direction(arm, bp, methods[chosen].beta, static, opt.offsets, sqv)
    # 7. validation, beside the textbook baseline fitted on the same samples
    baseline = textbook_baseline(W, Y, bp)
    validation = validate(methods, chosen, val_parts, phys, bp, baseline)
    fit_data = {"W": W, "Y": Y, "V": V, "weights": wts, "where": fit_where}
    friction_out = (fs_, fs_sd, fc_, fc_sd, fv_, fv_sd)
    if chosen == "simultaneous":
        # friction as the simultaneous method identified it (values of the exported, constrained model when there is
        # one; standard errors of the unconstrained estimate)
        for i in fr:
            kind, k = bp.lead(i).split("_")
            k = int(k) - 1
            val = methods[chosen].beta[i] if phys is None else phys.pi_[bp.std_names.index(bp.lead(i))]
            if kind == "B":
                fv_[k], fv_sd[k] = val, methods[chosen].std[i]
            elif kind == "fc":
                fc_[k], fc_sd[k] = val, methods[chosen].std[i]
        friction_out = (fs_, fs_sd, fc_, fc_sd, fv_, fv_sd)
    fsq = np.full(n, np.nan)
    for i in fr:
        if bp.lead(i).startswith("Bs_"):
            k = int(bp.lead(i).split("_")[1]) - 1
            fsq[k] = methods[chosen].beta[i] if phys is None else phys.pi_[bp.std_names.index(bp.lead(i))]
    return Identification(options=opt, arm=arm, bp=bp, logs=logs, inputs=inputs, notes=notes + post_notes,
                          static=static, friction_sqrt_viscous=fsq,
                          velocity=velocity, friction_static=friction_out[0], friction_static_std=friction_out[1],
                          friction_coulomb=friction_out[2], friction_coulomb_std=friction_out[3],
                          friction_viscous=friction_out[4], friction_viscous_std=friction_out[5], methods=methods,
                          chosen=chosen, condition_number=cond, condition_number_raw=cond_raw, n_fit_samples=len(W),
                          validation=validation, physical=phys, fit_data=fit_data,
                          val_data={"parts": val_parts, "where": val_where}, static_per_direction=static_dir)


def _term_cross_validation(W, Y, wts, bp: BaseParameters, prefix: str, folds: int = 3) -> tuple[bool, str]:
    """Does a group of columns (leads starting with ``prefix``) lower the held-out torque error of a weighted least
    squares fit in ``folds`` contiguous blocks of the *fit* data? Returns (keep, one-line account)."""
    N = len(W)
    edges = np.linspace(0, N, folds + 1).astype(int)
    with_ = np.arange(bp.n)
    without = np.array([i for i in range(bp.n) if not bp.lead(i).startswith(prefix)], int)
    err = {}
    for label, cols in (("with", with_), ("without", without)):
        e = 0.0
        for a, b in zip(edges[:-1], edges[1:]):
            tr = np.r_[0:a, b:N]
            sw = np.sqrt(wts[tr].reshape(-1))
            sol, *_ = np.linalg.lstsq(W[tr][:, :, cols].reshape(-1, len(cols)) * sw[:, None],
                                      Y[tr].reshape(-1) * sw, rcond=None)
            e += np.sum((W[a:b][:, :, cols] @ sol - Y[a:b]) ** 2)
        err[label] = float(np.sqrt(e / np.sum(Y ** 2)))
    keep = err["with"] < 0.98 * err["without"]
    return keep, (f"{folds}-fold cross-validation on the fit data, held-out torque error {100 * err['with']:.2f} % "
                  f"with, {100 * err['without']:.2f} % without")


PRIOR_WEIGHTS = (0.01, 0.1, 1.0, 10.0, 100.0, 1000.0)


def _physical_fit(W, Y, wts, mr: MethodResult, weight, bp, arm, motor_cols, fixed_std, nonneg, scale,
                  beta_hat=None) -> PhysicalConsistencyFit:
    """Physically consistent standard parameters (links, J_a >= 0, fitted friction >= 0, offsets) closest to the data
    ``W, Y`` (weighted rows) in the metric of its information matrix, pulled toward the URDF by ``weight``."""
    Hn = W.reshape(-1, bp.n) * np.sqrt(wts.reshape(-1, 1))
    gram = Hn.T @ Hn / scale
    return PhysicalConsistencyFit(prior_weight=weight).fit(
        bp.E, mr.beta if beta_hat is None else beta_hat, gram, arm.nominal_inertial, arm.n, motor_cols, fixed_std,
        nonneg)


def cross_validated_prior_weight(W, Y, wts, mr: MethodResult, bp, arm, motor_cols, fixed_std, nonneg, scale,
                                 weights=PRIOR_WEIGHTS, folds: int = 3) -> tuple[float, dict]:
    """The prior weight (pull toward the URDF) with the lowest held-out torque error in ``folds`` contiguous blocks of
    the *fit* data (each block predicted by the model fitted on the others). Validation data never enter."""
    N = len(W)
    edges = np.linspace(0, N, folds + 1).astype(int)
    fixed_b = np.setdiff1d(np.arange(bp.n), mr.free)
    err = np.zeros(len(weights))
    for a, b in zip(edges[:-1], edges[1:]):
        tr = np.r_[0:a, b:N]
        Wt, Yt, wt = W[tr], Y[tr], wts[tr]
        y = Yt - (Wt[:, :, fixed_b] @ mr.beta[fixed_b] if len(fixed_b) else 0.0)
        sw = np.sqrt(wt.reshape(-1))
        sol, *_ = np.linalg.lstsq(Wt[:, :, mr.free].reshape(-1, len(mr.free)) * sw[:, None], y.reshape(-1) * sw,
                                  rcond=None)
        bh = mr.beta.copy()
        bh[mr.free] = sol
        for k, wgt in enumerate(weights):
            ph = _physical_fit(Wt, Yt, wt, mr, wgt, bp, arm, motor_cols, fixed_std, nonneg, scale, beta_hat=bh)
            err[k] += np.sum((W[a:b] @ ph.beta_ - Y[a:b]) ** 2)
    rel = np.sqrt(err / np.sum(Y ** 2))
    best = int(np.argmin(rel))
    return float(weights[best]), {"weights": list(map(float, weights)), "rel_error": rel.tolist(),
                                  "folds": [(int(a), int(b)) for a, b in zip(edges[:-1], edges[1:])]}


def static_per_direction(arm, bp, beta, static, offsets, sqrt_viscous=False) -> dict:
    """f_s per direction from the breakaway torques and the identified gravity at each pose (motor -> values)."""
    out = {}
    poses = np.array([g["pose"] for g in static.gravity_], float)
    qm = (poses - arm.joint_offset) @ arm.Kinv.T
    z = np.zeros_like(qm)
    Wg = bp.project(build_regressor(arm, qm, z, z, offsets=offsets, sqrt_viscous=sqrt_viscous))
    G = Wg @ beta                          # (n_records, n): gravity (+ offsets) at each pose, motor side
    per = {}
    for r, g in enumerate(static.gravity_):
        m = g["motor"]
        per.setdefault(m, {"+": [], "-": []})
        per[m]["+"].append(g["tau_plus"] - G[r, m])
        per[m]["-"].append(G[r, m] - g["tau_minus"])
    for m, d in per.items():
        ent = {}
        for k in ("+", "-"):
            v = np.asarray(d[k])
            ent[k] = float(v.mean())
            ent[k + "_std"] = float(v.std(ddof=1) / np.sqrt(len(v))) if len(v) > 1 else float("nan")
        out[int(m)] = ent
    return out


def rms_nrms(pred: np.ndarray, meas: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-axis RMS of (pred - meas) and NRMS = RMS / (max - min of the measured torque)."""
    r = np.sqrt(np.mean((pred - meas) ** 2, axis=0))
    rng = np.ptp(meas, axis=0)
    return r, r / np.where(rng > 0, rng, np.nan)


def relative_error(pred: np.ndarray, meas: np.ndarray) -> tuple[np.ndarray, float]:
    """Relative torque error per axis ``||pred_k - meas_k|| / ||meas_k||`` and overall (Frobenius norms)."""
    e = pred - meas
    return (np.linalg.norm(e, axis=0) / np.linalg.norm(meas, axis=0),
            float(np.linalg.norm(e) / max(np.linalg.norm(meas), 1e-300)))


def textbook_baseline(W, Y, bp: BaseParameters) -> dict:
    """The textbook fit to compare with: plain OLS of the torque on the base regressor with Coulomb + viscous friction
    (no offsets, no weights, no constraints, no prior) on the same filtered fit samples as js2's model."""
    cols = np.array([i for i in range(bp.n) if not bp.lead(i).startswith(("off_", "Bs_"))], int)
    sol, *_ = np.linalg.lstsq(W[:, :, cols].reshape(-1, len(cols)), Y.reshape(-1), rcond=None)
    beta = np.zeros(bp.n)
    beta[cols] = sol
    return {"beta": beta, "description": "OLS on the base regressor with Coulomb + viscous friction, same filtered "
                                         "fit samples, no offsets/extra friction/weights/constraints/prior"}


def validate(methods, chosen, val_parts, phys, bp, baseline: dict | None = None) -> dict:
    Wv = np.concatenate([p[0] for p in val_parts])
    Yv = np.concatenate([p[1] for p in val_parts])
    out = {"data": [p[3] for p in val_parts], "samples": int(len(Wv))}
    for name, mr in methods.items():
        pred = Wv @ mr.beta
        r, nr = rms_nrms(pred, Yv)
        out[name] = {"rms": r, "nrms": nr, "pred": pred}
        for est in ("ols", "wls"):
            b = mr.beta.copy()
            b[mr.free] = getattr(mr, est).coef_
            r2, nr2 = rms_nrms(Wv @ b, Yv)
            out[f"{name}_{est}"] = {"rms": r2, "nrms": nr2}
    if phys is not None:
        pred = Wv @ phys.beta_
        r, nr = rms_nrms(pred, Yv)
        out["physical"] = {"rms": r, "nrms": nr, "pred": pred}
    if baseline is not None:
        pred = Wv @ baseline["beta"]
        r, nr = rms_nrms(pred, Yv)
        rel, rel_all = relative_error(pred, Yv)
        out["baseline"] = {"rms": r, "nrms": nr, "pred": pred, "rel": rel, "rel_overall": rel_all,
                           "description": baseline["description"]}
    # the exported model: the physically consistent one (robot_identified.urdf + model.yaml) when fitted
    exp = "physical" if phys is not None else chosen
    out["exported"] = exp
    out["measured"] = Yv
    out["rms"] = out[exp]["rms"]
    out["nrms"] = out[exp]["nrms"]
    out["rel"], out["rel_overall"] = relative_error(Wv @ (phys.beta_ if phys is not None else methods[chosen].beta), Yv)
    return out


def predict_standard(ident: Identification, pi: np.ndarray, part: str = "validation") -> tuple[np.ndarray, np.ndarray]:
    """Filtered torque predicted by a *standard* parameter vector (e.g. the simulator's truth) on the same samples and
    through the same filters as the identified model (returns prediction, measurement). For tests and reports."""
    beta = ident.bp.beta(pi)
    if part == "validation":
        Wv = np.concatenate([p[0] for p in ident.val_data["parts"]])
        Yv = np.concatenate([p[1] for p in ident.val_data["parts"]])
    else:
        Wv, Yv = ident.fit_data["W"], ident.fit_data["Y"]
    return Wv @ beta, Yv
