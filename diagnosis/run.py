"""The diagnosis from files to findings: model.yaml + a recording -> located, named, modelled, proven."""
from __future__ import annotations

import copy
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from js2spec.log import join_logs, read_log
from js2spec.model import IdentifiedModel, load_model

from .library import LIBRARY, ThermalDrift, model_data_library
from .locate import band_shares, dominant_band, locate
from .residual import ResidualData, extra_once, own_offsets, own_recordings, part_rows, residual_data
from .search import MismatchSearch, Scored, _on_motors


@dataclass
class DiagnoseOptions:
    holdout_trial: str = "validation"
    fit_trials: list[str] | None = None
    kinds: list[str] | None = None
    min_gain: float = 0.12
    min_fit_gain: float | None = None     # None: MismatchSearch.MIN_FIT_GAIN (0.18), or min_gain when that is higher
    max_terms: int = 4
    min_speed: float = 0.01         # rad/s at the joint: slower samples are left out (friction is undefined at rest)
    payload_removed: bool = False   # a payload_change may read a negative mass (a tool taken off since identification)
    progress: bool = False


@dataclass
class DiagnosisResult:
    model: IdentifiedModel
    log_path: Path
    rd: ResidualData
    search: MismatchSearch
    location: dict
    notes: list[str] = field(default_factory=list)
    log_paths: list[Path] = field(default_factory=list)   # every file of the session (log_path is the first)

    @property
    def accepted(self) -> list[Scored]:
        return self.search.accepted_

    def findings(self) -> list[dict]:
        """Accepted terms as findings, in the order found. A joint_elasticity and a backlash accepted on the same
        joint are one finding: backlash (the play, with its contact stiffness) — the elastic term accepted first
        is the compliance part of it (nested models: the play was accepted only because it still improved the
        held-out fit on top of the spring)."""
        rows = []
        for s in self.accepted:
            row = s.row(self.rd.joints)
            row["holdout_rms_before"] = s.rms_before.tolist()
            row["holdout_rms_after"] = s.rms_after.tolist()
            rows.append(row)
        merged = []
        for row in rows:
            twin = next((m for m in merged if m["joint_index"] == row["joint_index"]
                         and {m["kind"], row["kind"]} == {"joint_elasticity", "backlash"}), None)
            if twin is None:
                merged.append(row)
                continue
            el, bl = (twin, row) if twin["kind"] == "joint_elasticity" else (row, twin)
            combined = dict(bl)
            combined["summary"] = (f"{bl['summary']}; with the transmission compliance of the elastic term "
                                   f"(about {el['effect']['stiffness']:.3g} N*m/rad)")
            combined["holdout_rms_before"] = twin["holdout_rms_before"]
            combined["holdout_rms_after"] = row["holdout_rms_after"]
            combined["holdout_gain"] = 1 - (1 - el["holdout_gain"]) * (1 - bl["holdout_gain"])
            combined["merged"] = ["joint_elasticity", "backlash"]
            merged[merged.index(twin)] = combined
        return merged

    def to_dict(self) -> dict:
        base = self.search.baseline_
        fin = self.search.final_
        runners = []
        if self.search.rankings_:
            for s in self.search.rankings_[0][:8]:
                runners.append(s.row(self.rd.joints))
        return {
            "model": str(self.model.path), "recording": str(self.log_path),
            "recordings": [str(p) for p in (self.log_paths or [self.log_path])],
            "split": self.rd.split_note,
            "rows": {name: int((self.rd.mask & part_rows(rows, self.rd.n)).any(axis=1).sum()) for name, rows in
                     (("fit", self.rd.fit_rows), ("select", self.rd.select_rows), ("report", self.rd.holdout_rows))},
            "sample_rate_hz": self.rd.fs,
            "filters_hz": {"velocity": self.rd.signals.settings.fc_velocity_hz,
                           "acceleration_and_torque": self.rd.signals.settings.fc_acceleration_hz},
            "torque_side": self.rd.torque_side,
            "min_speed_joint_rad_s": self.rd.extra.get("min_speed"),
            "min_speed_motor_rad_s": self.rd.min_speed_motor.tolist(),
            "candidates_tried": self.search.tried_,
            "location": self.location,
            "findings": self.findings(),
            "verdict": self.verdict(),
            "unexplained": self.unexplained(),
            "holdout_rms": {"before": base["low"]["holdout"].tolist(), "after": fin["low"]["holdout"].tolist(),
                            "band": "torque band (acceleration filter)"},
            "holdout_rms_wide": {"before": base["wide"]["holdout"].tolist(),
                                 "after": fin["wide"]["holdout"].tolist(), "band": "unfiltered"},
            "holdout_gain": self.search.score(self.rd, "own"),
            "holdout_gain_bands": self.search.motor_bands(self.rd),
            "holdout_gain_definition": "report rows only (never seen by the search): 1 - sum of squared residual "
                                       "after / before the found terms, each motor's residual scaled by its RMS on "
                                       "the fit rows; each motor in the band its findings were proven in "
                                       "(holdout_gain_bands: 'low' the torque band, 'wide' unfiltered, for cogging "
                                       "ripple or a play's rattle); a finding's own gain on the motors it moves, an "
                                       "elasticity's or a backlash's on the motor of the joint it names",
            "candidates_step1": runners,
            "dropped": [dict(s.row(self.rd.joints), why_not=why) for s, why in getattr(self.search, "dropped_", [])],
            "notes": self.notes,
        }

    def unexplained(self) -> list[dict]:
        """Structure no named term explains: reference terms (a refit of the model's own friction) that
        passed every test, with where (joint, regime, frequency band of the torque the refit takes out) and how much
        of that motor's select-rows residual they take."""
        out = []
        for s in self.search.references_:
            j = s.fitted.joint
            mot = self.location["motors"][j] if self.location else {}
            term = s.term
            took = (_on_motors(term.columns(self.rd, j, s.fitted.hyper), term.motors(self.rd, j)) @ s.fitted.coef)[:, j]
            band, share = dominant_band(band_shares(took, self.rd.fs, self.rd.mask[:, j]))
            out.append({"kind": "unexplained", "joint": self.rd.joints[j], "joint_index": j,
                        "regime": mot.get("worst_regime"), "frequency_band": band,
                        "frequency_band_share": None if band is None else round(float(share), 4),
                        "fraction_of_residual": round(float(s.select_gain), 4),
                        "holdout_gain": float(s.holdout_gain), "reference": s.fitted.kind,
                        "what": s.demoted or f"{term.unexplained_what}: {s.fitted.summary}"})
        return out

    def verdict(self) -> str:
        if self.accepted:
            return "the model leaves out: " + "; ".join(f"{f['kind']} on {f['joint']} ({f['summary']})"
                                                       for f in self.findings())
        if self.search.references_:
            # each joint once, with the readings (references) that take its structure: a refit of the model's own
            # friction, a constant torque, a compliance, ... (Term.unexplained_what says what each stands for)
            takes = {}
            for s in self.search.references_:
                takes.setdefault(self.rd.joints[s.fitted.joint], []).append(s.fitted.kind)
            return ("unexplained: the residual has structure on "
                    + ", ".join(f"{j} (what takes it: {', '.join(dict.fromkeys(k))})" for j, k in takes.items())
                    + " that no named effect explains better: nothing named")
        return "none: no candidate term improves the fit on held-out data enough: nothing named"

    def diagnosed_model(self) -> dict:
        """model.yaml extended with ``unmodelled:`` (the effects found, in hil_sim's effect format)."""
        d = copy.deepcopy(self.model.raw)
        d["unmodelled"] = [dict(f["effect"], holdout_gain=round(float(f["holdout_gain"]), 4),
                                found_on=", ".join(str(p) for p in (self.log_paths or [self.log_path])))
                              for f in self.findings()]
        return d

    def sim_effects(self) -> list[dict]:
        """The found effects as ``hil_sim`` effect configs (Plant(effects=...), sim_truth.yaml ``effects:``). A
        Stribeck finding carries its fitted breakaway level ``static`` = the model's f_c (motor side) + the fitted
        hump, so it simulates as found even with a model without f_s (the simultaneous method)."""
        out = []
        for f in self.findings():
            e = dict(f["effect"])
            if e.get("kind") == "stribeck" and e.get("static") is None and f.get("coefficients"):
                j = int(e["joints"][0])
                fc = float(self.model.friction_coulomb[j])
                if self.rd.torque_side == "joint":
                    fc *= abs(float(self.rd.K[j, j]))
                e["static"] = max(0.0, fc + float(f["coefficients"][0]))
            out.append(e)
        return out


MIN_NAMING_SPAN_S = 5.0     # s: a recording shorter than this names no effect (see diagnose)


#: Hz: a recording sampled slower than this gets :func:`slow_log_note`. The benchmark's 260 cases read every 5th or
#: 10th cycle (100 Hz; 250 Hz cases every 2nd, 125 Hz) named 31 of 61 elasticities and 41 of 57 plays against 40 and
#: 49 at their drawn 250-1000 Hz (docs/diagnosis.md, stop 33)
SLOW_LOG_HZ = 200.0


def slow_log_note(fs: float) -> str:
    """What a recording sampled at ``fs`` Hz (under ``SLOW_LOG_HZ``) cannot show well, in one sentence ('' above it):
    a gear's oscillation above the torque band is read up to fs / 2 only, and two central differences keep
    (sin wT / wT)^2 of its acceleration (the plays' and springs' readings above the band need it); a torque read
    once per cycle carries its noise of the whole 0 to fs / 2 into the torque band."""
    if fs >= SLOW_LOG_HZ:
        return ""

    def kept(f):
        x = 2 * np.pi * f / fs
        return (np.sin(x) / x) ** 2

    return (f"sampled at {fs:g} Hz: a gear's oscillation above the torque band is read up to {fs / 2:g} Hz only, and "
            f"the differentiated angle keeps {kept(fs / 4):.0%} of its acceleration at {fs / 4:g} Hz, "
            f"{kept(0.37 * fs):.0%} at {0.37 * fs:.3g} Hz (the drives' limit cycles lie at 30-40 Hz); the torque "
            f"(a current or a sensor), read once per cycle, brings its noise of 0-{fs / 2:g} Hz into the torque "
            "band. Plays, springs and fine ripples show less than at 500 Hz or more: 'nothing' on them is weaker "
            "evidence here (docs/diagnosis.md, stop 33)")


def diagnose(model: str | Path | IdentifiedModel, log_path: str | Path | list,
             options: DiagnoseOptions | None = None) -> DiagnosisResult:
    """Diagnose one recording, or one session recorded over several files (a list: joined in the order given,
    each file filtered as its own run, :func:`js2spec.log.join_logs`)."""
    opt = options or DiagnoseOptions()
    mdl = model if isinstance(model, IdentifiedModel) else load_model(model)
    paths = [Path(p) for p in log_path] if isinstance(log_path, (list, tuple)) else [Path(log_path)]
    logs = [read_log(p) for p in paths]
    log = join_logs(logs)
    notes = []
    library = LIBRARY
    own = [p.name for p, lg in zip(paths, logs) if mdl.is_input(lg)]       # the model's own recordings
    if own:
        library = model_data_library(LIBRARY)
        notes.append(f"{', '.join(own)}: the model was identified from this recording (its sha256 or its data's is "
                     "one of the model's inputs), so a constant torque per motor is a choice of the model's own "
                     "structure (`js2-identify --offsets`), reported unexplained, not named")
    if len(paths) > 1:
        notes.append(f"one session over {len(paths)} files, joined in the order given (each filtered on its own): "
                     + ", ".join(p.name for p in paths))
    if log.truncated or log.recovered_note:
        notes.append(log.recovered_note)
    notes.extend(log.warnings)
    rd = residual_data(mdl, log, holdout_trial=opt.holdout_trial, fit_trials=opt.fit_trials,
                       min_speed=opt.min_speed)
    rd.extra["payload_removed"] = bool(opt.payload_removed)
    if not own:       # what the model leaves on its own recordings, read only if an offset or a coupling is about to
        # be named (read once for both)
        rd.extra["own_recordings"] = lambda: own_recordings(mdl, min_speed=opt.min_speed)
        rd.extra["own_offsets"] = lambda: own_offsets(mdl, min_speed=opt.min_speed,
                                                      recordings=extra_once(rd, "own_recordings"))
    if rd.signals.note and rd.signals.note != "no lost or invalid cycles":
        notes.append(rd.signals.note)
    if ThermalDrift.too_short(rd) and (opt.kinds is None or "thermal_drift" in opt.kinds):
        notes.append(f"thermal drift not looked for: the recording spans {float(rd.t[-1] - rd.t[0]):.3g} s, under "
                     f"{ThermalDrift.MIN_SPAN:g} x the fastest thermal lag tried ({ThermalDrift.TAU_MIN:g} s): there "
                     "any slow trend reads as heating")
    progress = None
    if opt.progress:
        from tqdm import tqdm

        def progress(it, desc=""):
            return tqdm(it, desc=desc, leave=False, disable=None)   # None: terminals only
    search = MismatchSearch(library=library, kinds=opt.kinds, min_gain=opt.min_gain, max_terms=opt.max_terms,
                            min_fit_gain=opt.min_fit_gain, progress=progress).fit(rd)
    for s, why in search.dropped_:
        notes.append(f"{s.fitted.kind} on {rd.joints[s.fitted.joint]} ({s.fitted.summary}): {why}")
    span = float(rd.t[-1] - rd.t[0])
    if span < MIN_NAMING_SPAN_S:
        for s in search.accepted_:
            s.demoted = (f"{s.fitted.kind} fits here ({s.fitted.summary}), but {span:.3g} s of recording is too short "
                         f"to name an effect (at least {MIN_NAMING_SPAN_S:g} s)")
        search.references_ = search.accepted_ + search.references_
        search.accepted_ = []
        notes.append(f"nothing named: the recording spans {span:.3g} s, under {MIN_NAMING_SPAN_S:g} s; its fit, select "
                     "and report rows are a few seconds' blocks of one motion, where a term fitted on one block "
                     "explains the next by chance (a 2.5 s piece of the real TX40 recording named an asymmetric "
                     "friction that doubled the error on its report rows); what the search found is reported "
                     "unexplained")
    loc = locate(rd, search)
    slow = slow_log_note(rd.fs)
    if slow:
        notes.append(slow)
    if (rd.signals.settings.fc_velocity_hz, rd.signals.settings.fc_acceleration_hz) != (
            (mdl.raw.get("filters") or {}).get("velocity_cutoff_hz", 50.0),
            (mdl.raw.get("filters") or {}).get("acceleration_cutoff_hz", 7.0)):
        notes.append(f"filters: {rd.signals.settings.fc_velocity_hz:g} Hz velocity, "
                     f"{rd.signals.settings.fc_acceleration_hz:g} Hz acceleration/torque (the model's cut-offs "
                     f"kept below 0.4 x the {rd.fs:g} Hz sample rate)")
    return DiagnosisResult(model=mdl, log_path=paths[0], log_paths=paths, rd=rd, search=search, location=loc, notes=notes)
