"""Writers of OUTDIR: ``model.yaml``, ``robot_identified.urdf``, ``verdict.json`` (the report is in report.py).

``model.yaml`` is read back by ``js2spec.model.load_model`` (the one loader). Keys: ``joints``,
``friction: {static, coulomb, viscous}`` (+ ``*_std``, per direction), ``motor_inertia`` (per motor, kg m^2, motor side;
``motor_inertia_std``, ``motor_inertia_separately_identified``), ``base_parameters: {names, values, std}``,
``validation: {rms, nrms}``, ``method``, ``inputs`` (path + sha256 + data_sha256 of each log), ``condition_number``, ``links`` (the
physically consistent standard parameters), ``methods`` (all estimates: mixed/simultaneous x RLS/OLS/WLS).
"""
from __future__ import annotations

import datetime as _dt
import json
from pathlib import Path

import numpy as np
import yaml

from .consistency import is_physical
from .plausibility import plausibility_checks


def _l(x) -> list:
    return [None if (v is None or not np.isfinite(v)) else float(v) for v in np.asarray(x, float).ravel()]


def model_dict(ident) -> dict:
    arm, bp, mr = ident.arm, ident.bp, ident.model
    ja, ja_sd, alone = ident.motor_inertia()
    d = {
        "format": "js2-model",
        "version": 1,
        "robot": ident.logs[0].robot,
        "created": _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
        "method": {"mixed": "mixed (compound): friction from the sequential tests (eq. 2-5), inertial parameters by "
                            "RLS with friction fixed",
                   "simultaneous": "simultaneous: all parameters by RLS over the acceleration trial"}[ident.chosen],
        "method_key": ident.chosen,
        "torque_side": arm.torque_side,
        "joints": list(arm.joints),
        "units": "SI; motor side per drive (torque_side motor) else joint side",
        "inputs": ident.inputs,
        "notes": list(ident.notes),
        "filters": {"velocity_cutoff_hz": ident.options.filters.fc_velocity_hz,
                    "acceleration_cutoff_hz": ident.options.filters.fc_acceleration_hz,
                    "order": ident.options.filters.order, "zero_phase": True,
                    "edge_trim_s": ident.options.filters.trim, "reason": ident.options.filters.reason},
        "friction": {
            "static": _l(ident.friction_static), "static_std": _l(ident.friction_static_std),
            "coulomb": _l(ident.friction_coulomb), "coulomb_std": _l(ident.friction_coulomb_std),
            "viscous": _l(ident.friction_viscous), "viscous_std": _l(ident.friction_viscous_std),
        },
        "motor_inertia": _l(ja),
        "torque_offset": _l(_offsets(ident)),
        "motor_inertia_std": _l(ja_sd),
        "motor_inertia_separately_identified": [bool(a) for a in alone],
        "base_parameters": {"names": list(bp.names), "values": _l(mr.beta), "std": _l(mr.std),
                            "lead": [bp.lead(i) for i in range(bp.n)]},
        "condition_number": float(ident.condition_number),
        "condition_number_unscaled": float(ident.condition_number_raw),
        "rls": {"iterations": int(mr.rls.n_iter_), "checkpoints": len(mr.history_iter)},
        "fit_samples": int(ident.n_fit_samples),
        "validation": {"rms": _l(ident.validation["rms"]), "nrms": _l(ident.validation["nrms"]),
                       "data": ident.validation["data"], "samples": ident.validation["samples"],
                       "nrms_definition": "rms / (max - min) of the measured (filtered) torque on the validation data"},
    }
    fsq = ident.friction_sqrt_viscous
    if fsq is not None and np.isfinite(fsq).any():
        d["friction"]["sqrt_viscous"] = _l(fsq)
        d["friction"]["sqrt_viscous_note"] = ("extra friction Bs sgn(v) sqrt|v| per axis (N m (s/rad)^0.5, same side "
                                              "as viscous), kept because it lowered the held-out error in "
                                              "cross-validation on the fit data")
    if ident.velocity is not None:
        pdirs = {}
        for m, ax in ident.velocity.axes_.items():
            if ax.per_direction:
                pdirs[arm.joints[m]] = {k: {"viscous": v[0], "coulomb": v[1]} for k, v in ax.per_direction.items()}
        d["friction"]["per_direction"] = pdirs
    if ident.static_per_direction:
        d["friction"]["static_per_direction"] = {
            arm.joints[m]: {"positive": v["+"], "negative": v["-"], "positive_std": _l([v["+_std"]])[0],
                            "negative_std": _l([v["-_std"]])[0]}
            for m, v in sorted(ident.static_per_direction.items())}
        d["friction"]["static_per_direction_note"] = (
            "f_s+ = tau+ - G(pose), f_s- = G(pose) - tau- with G from the identified model (eq. 2); "
            "'static' is eq. 3's (tau+ - tau-)/2, their mean")
    if ident.static is not None:
        d["static_test"] = {"gravity_at_poses": ident.static.gravity_,
                            "pairs_per_motor": [int(x) for x in ident.static.pairs_]}
    methods = {}
    for name, m in ident.methods.items():
        ent = {}
        for est in ("rls", "ols", "wls"):
            e = getattr(m, est)
            vals = m.beta.copy()
            sd = m.std.copy()
            vals[m.free] = e.coef_
            sd[m.free] = e.std_
            ent[est] = {"values": _l(vals), "std": _l(sd)}
        ent["validation_rms"] = _l(ident.validation[name]["rms"])
        methods[name] = ent
    d["methods"] = methods
    if ident.physical is not None:
        links = {}
        for i, lk in enumerate(arm.links):
            p = ident.physical.links_[i]
            m = p[0]
            c = p[1:4] / m
            links[lk] = {"mass": float(m), "com": _l(c), "inertia_com": _l(_inertia_com(p)),
                         "physically_consistent": bool(is_physical(p, 1e-12))}
        d["links"] = links
        d["links_note"] = ("physically consistent standard parameters fitted to the base parameters (log-Cholesky); "
                           "inertia_com = [ixx, ixy, ixz, iyy, iyz, izz] about the centre of mass in the link frame")
        d["validation"]["rms_physical"] = _l(ident.validation["physical"]["rms"])
        cv = getattr(ident.physical, "prior_weight_cv_", None)
        d["links_prior_weight"] = float(ident.physical.prior_weight)
        if cv is not None:
            d["links_prior_weight_cv"] = {"weights": cv["weights"], "held_out_relative_error": cv["rel_error"],
                                          "folds_fit_rows": [list(f) for f in cv["folds"]]}
    val = ident.validation
    d["validation"]["model"] = val["exported"]
    d["validation"]["relative_error"] = _l(val["rel"])
    d["validation"]["relative_error_overall"] = float(val["rel_overall"])
    if "baseline" in val:
        b = val["baseline"]
        d["validation"]["baseline"] = {"description": b["description"], "rms": _l(b["rms"]), "nrms": _l(b["nrms"]),
                                       "relative_error": _l(b["rel"]), "relative_error_overall": float(b["rel_overall"]),
                                       "ratio_js2_to_baseline": float(val["rel_overall"] / b["rel_overall"])}
    d["urdf"] = "robot_identified.urdf"
    return d


def _offsets(ident) -> np.ndarray:
    """Constant torque offset per axis of the exported model (0 when offsets are not modelled)."""
    out = np.zeros(ident.arm.n)
    names = ident.bp.std_names
    for k in range(ident.arm.n):
        nm = f"off_{k + 1}"
        if nm in names:
            if ident.physical is not None:
                out[k] = ident.physical.pi_[names.index(nm)]
            else:
                i = ident.bp.index_of(nm)
                out[k] = ident.model.beta[i] if i is not None else 0.0
    return out


def _inertia_com(p10):
    m = p10[0]
    c = p10[1:4] / m
    ixx, ixy, iyy, ixz, iyz, izz = p10[4:]
    Io = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
    Ic = Io - m * (np.dot(c, c) * np.eye(3) - np.outer(c, c))
    return [Ic[0, 0], Ic[0, 1], Ic[0, 2], Ic[1, 1], Ic[1, 2], Ic[2, 2]]


def write_model(ident, outdir: Path) -> Path:
    d = model_dict(ident)
    p = outdir / "model.yaml"
    header = ("# js2 identified model (written by js2-identify). Load with js2spec.model.load_model.\n"
              "# SI units; friction and motor_inertia per motor on the motor side (eq. 1).\n")
    p.write_text(header + yaml.safe_dump(d, sort_keys=False, width=120))
    return p


def identified_urdf(ident) -> str:
    """The input URDF with each moving body's <inertial> replaced by the physically consistent identified one.

    Pinocchio lumps links attached by fixed joints into the moving body; their own <inertial> is removed (the lumped
    body carries them), with a comment saying so."""
    import xml.etree.ElementTree as ET

    arm = ident.arm
    root = ET.fromstring(arm.urdf_text)
    links = {lk.get("name"): lk for lk in root.findall("link")}
    parent_of = {}
    fixed_children = {}
    for j in root.findall("joint"):
        child = j.find("child").get("link")
        parent = j.find("parent").get("link")
        parent_of[child] = (parent, j.get("type"))
        if j.get("type") == "fixed":
            fixed_children.setdefault(parent, []).append(child)
    moving = set(arm.links)
    if ident.physical is None:
        return arm.urdf_text
    for i, lk in enumerate(arm.links):
        el = links.get(lk)
        if el is None:
            continue
        p = ident.physical.links_[i]
        m = float(p[0])
        c = p[1:4] / m
        Ic = _inertia_com(p)
        for old in el.findall("inertial"):
            el.remove(old)
        inert = ET.SubElement(el, "inertial")
        ET.SubElement(inert, "origin", xyz=" ".join(f"{v:.9g}" for v in c), rpy="0 0 0")
        ET.SubElement(inert, "mass", value=f"{m:.9g}")
        ET.SubElement(inert, "inertia", ixx=f"{Ic[0]:.9g}", ixy=f"{Ic[1]:.9g}", ixz=f"{Ic[2]:.9g}",
                      iyy=f"{Ic[3]:.9g}", iyz=f"{Ic[4]:.9g}", izz=f"{Ic[5]:.9g}")
        # links welded to this body (fixed joints, recursively) are part of the identified body now
        stack = list(fixed_children.get(lk, []))
        while stack:
            ch = stack.pop()
            if ch in moving:
                continue
            cel = links.get(ch)
            if cel is not None:
                for old in cel.findall("inertial"):
                    cel.remove(old)
                cel.insert(0, ET.Comment(f" inertial lumped into identified body {lk} "))
            stack += fixed_children.get(ch, [])
    body = ET.tostring(root, encoding="unicode")
    head = ("<?xml version=\"1.0\"?>\n<!-- robot_identified.urdf: written by js2-identify. Inertials of the moving "
            "links are the identified, physically consistent parameters (method: "
            f"{ident.chosen}); motor inertia and friction are in model.yaml. -->\n")
    return head + body


def write_urdf(ident, outdir: Path) -> Path:
    p = outdir / "robot_identified.urdf"
    p.write_text(identified_urdf(ident))
    return p


DEFAULT_THRESHOLDS = {
    "condition_number_max": 1000.0,        # column-normalised base regressor on the fitting data
    "validation_nrms_max": 0.10,           # per axis: rms / range of measured torque
    "physically_consistent": True,
}


def verdict(ident, thresholds: dict | None = None) -> dict:
    th = dict(DEFAULT_THRESHOLDS)
    th.update(thresholds or {})
    checks = []
    checks.append({"check": "condition_number", "value": float(ident.condition_number),
                   "threshold": th["condition_number_max"],
                   "pass": bool(ident.condition_number <= th["condition_number_max"])})
    nrms = np.asarray(ident.validation["nrms"], float)
    for k, j in enumerate(ident.arm.joints):
        v = float(nrms[k]) if np.isfinite(nrms[k]) else None
        checks.append({"check": f"validation_nrms[{j}]", "value": v, "threshold": th["validation_nrms_max"],
                       "pass": bool(v is not None and v <= th["validation_nrms_max"])})
    if th.get("physically_consistent") and ident.physical is not None:
        ok = bool(np.all(ident.physical.physical_))
        checks.append({"check": "physically_consistent_links", "value": ok, "threshold": True, "pass": ok})
    fr = np.concatenate([ident.friction_coulomb, ident.friction_viscous])
    checks.append({"check": "friction_identified_and_non_negative", "value": bool(np.all(np.isfinite(fr)) and
                                                                                   np.all(fr >= 0)),
                   "threshold": True, "pass": bool(np.all(np.isfinite(fr)) and np.all(fr >= 0))})
    checks += plausibility_checks(ident)
    ok = all(c["pass"] for c in checks)
    reasons = [c["reason"] for c in checks if not c["pass"] and c.get("reason")]
    return {"pass": ok, "reasons": reasons, "method": ident.chosen, "thresholds": th, "checks": checks,
            "truncated_input": any(i["truncated"] for i in ident.inputs), "notes": list(ident.notes)}


def write_verdict(ident, outdir: Path, thresholds: dict | None = None) -> dict:
    v = verdict(ident, thresholds)
    (outdir / "verdict.json").write_text(json.dumps(v, indent=2))
    return v
