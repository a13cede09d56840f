"""The diagnosis from files to findings: model.yaml + a recording -> located, named, modelled, proven."""
from __future__ import annotations

import copy
from dataclasses import dataclass, field
from pathlib import Path

from js2spec.log import read_log
from js2spec.model import IdentifiedModel, load_model

from .locate import locate
from .residual import ResidualData, residual_data
from .search import MismatchSearch, Scored


@dataclass
class DiagnoseOptions:
    holdout_trial: str = "validation"
    fit_trials: list[str] | None = None
    kinds: list[str] | None = None
    min_gain: float = 0.12
    max_terms: int = 3
    min_speed: float = 1.0          # rad/s motor: slower samples are left out (friction is undefined at rest)
    progress: bool = False


@dataclass
class DiagnosisResult:
    model: IdentifiedModel
    log_path: Path
    rd: ResidualData
    search: MismatchSearch
    location: dict
    notes: list[str] = field(default_factory=list)

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
            "split": self.rd.split_note,
            "min_speed_rad_s": self.rd.extra.get("min_speed"),
            "location": self.location,
            "findings": self.findings(),
            "verdict": (f"the model leaves out: " + "; ".join(f"{f['kind']} on {f['joint']} ({f['summary']})"
                                                          for f in self.findings())
                        if self.accepted else "no candidate term improves the held-out fit enough: "
                                              "nothing named"),
            "holdout_rms": {"before": base["low"]["holdout"].tolist(), "after": fin["low"]["holdout"].tolist(),
                            "band": "torque band (acceleration filter)"},
            "holdout_rms_wide": {"before": base["wide"]["holdout"].tolist(),
                                 "after": fin["wide"]["holdout"].tolist(), "band": "unfiltered"},
            "holdout_gain": self.search.score(self.rd, "low"),
            "candidates_step1": runners,
            "notes": self.notes,
        }

    def diagnosed_model(self) -> dict:
        """model.yaml extended with ``unmodelled:`` (the effects found, in hil_sim's effect format)."""
        d = copy.deepcopy(self.model.raw)
        d["unmodelled"] = [dict(f["effect"], holdout_gain=round(float(f["holdout_gain"]), 4),
                                found_on=str(self.log_path)) for f in self.findings()]
        return d

    def sim_effects(self) -> list[dict]:
        """The found effects as ``hil_sim`` effect configs (Plant(effects=...), sim_truth.yaml ``effects:``)."""
        return [dict(f["effect"]) for f in self.findings()]


def diagnose(model: str | Path | IdentifiedModel, log_path: str | Path,
             options: DiagnoseOptions | None = None) -> DiagnosisResult:
    opt = options or DiagnoseOptions()
    mdl = model if isinstance(model, IdentifiedModel) else load_model(model)
    log = read_log(log_path)
    notes = []
    if log.truncated:
        notes.append(log.recovered_note)
    notes.extend(log.warnings)
    rd = residual_data(mdl, log, holdout_trial=opt.holdout_trial, fit_trials=opt.fit_trials,
                       min_speed=opt.min_speed)
    if rd.signals.note and rd.signals.note != "no lost or invalid cycles":
        notes.append(rd.signals.note)
    progress = None
    if opt.progress:
        from tqdm import tqdm

        def progress(it, desc=""):
            return tqdm(it, desc=desc, leave=False, disable=None)   # None: terminals only
    search = MismatchSearch(kinds=opt.kinds, min_gain=opt.min_gain, max_terms=opt.max_terms,
                            progress=progress).fit(rd)
    loc = locate(rd, search)
    return DiagnosisResult(model=mdl, log_path=Path(log_path), rd=rd, search=search, location=loc, notes=notes)
