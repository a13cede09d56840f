"""Evaluate another model (a published URDF, published friction values, the simulator's truth) on exactly the samples
and through exactly the filters that validated the identified model, so their torque RMS can stand side by side."""
from __future__ import annotations

import numpy as np

from .base import BaseParameters
from .pipeline import _regressor_rows, rms_nrms
from .regressor import arm_model, column_groups, standard_names, standard_vector


def _identity_bp(names) -> BaseParameters:
    p = len(names)
    return BaseParameters(std_names=list(names), base_index=np.arange(p), E=np.eye(p), names=list(names),
                          zero_index=np.arange(0))


def _rows(arm, where, offsets, sqrt_viscous=False):
    bp = _identity_bp(standard_names(arm, offsets, sqrt_viscous))
    Ws, Ys = [], []
    for sig, idx in where:
        W, Y, _ = _regressor_rows(arm, bp, sig, idx, offsets, None, sqrt_viscous)
        Ws.append(W), Ys.append(Y)
    return np.concatenate(Ws), np.concatenate(Ys)


def published_friction(urdf_text: str, joints: list[str]) -> dict:
    """The friction a URDF publishes (``<dynamics damping=... friction=...>`` per joint) as fixed reference values
    ``{"B_k": damping, "fc_k": friction}`` (k: 1-based drive order of ``joints``), for :func:`reference_prediction`."""
    import xml.etree.ElementTree as ET

    fixed = {}
    for j in ET.fromstring(urdf_text).findall("joint"):
        dyn = j.find("dynamics")
        if dyn is not None and j.get("name") in joints:
            k = joints.index(j.get("name")) + 1
            fixed[f"B_{k}"] = float(dyn.get("damping", 0))
            fixed[f"fc_{k}"] = float(dyn.get("friction", 0))
    return fixed


def reference_prediction(ident, urdf_text: str | None = None, fixed: dict | None = None, refit: bool = True):
    """Validation-sample torque predicted by a reference model, and the measurement it is compared with.

    ``urdf_text``: the reference's kinematics and inertials (default: the log's URDF); ``fixed``: standard-parameter
    values by name (``Ja_k``, ``B_k``, ``fc_k``, ``off_k``, or link names); with ``refit`` the drive terms not in
    ``fixed`` (motor inertia, Coulomb + viscous friction, offsets when the identified model has them or ``fixed``
    names them) are least-squares fitted on the fitting samples with the inertials held, otherwise they are 0.
    Returns ``(pred, meas, pi)``."""
    drives = ident.logs[0].drives
    fixed = fixed or {}
    offsets = bool(ident.options.offsets) or any(k.startswith("off_") for k in fixed)
    arm = arm_model(urdf_text or ident.arm.urdf_text, drives)
    names = standard_names(arm, offsets)
    pi = standard_vector(arm, offsets=offsets)
    known = np.zeros(len(pi), dtype=bool)
    known[column_groups(arm, offsets)["inertial"]] = True
    for k, v in fixed.items():
        j = names.index(k)
        pi[j] = v
        known[j] = True
    if refit and not known.all():
        Wf, Yf = _rows(arm, ident.fit_data["where"], offsets)
        A = Wf.reshape(-1, len(pi))
        y = Yf.reshape(-1) - A[:, known] @ pi[known]
        free = np.flatnonzero(~known)
        sol, *_ = np.linalg.lstsq(A[:, free], y, rcond=None)
        pi[free] = sol
    Wv, Yv = _rows(arm, ident.val_data["where"], offsets)
    return Wv @ pi, Yv, pi


def reference_rms(ident, urdf_text: str | None = None, fixed: dict | None = None, refit: bool = True):
    """RMS/NRMS per axis on the validation samples of a reference model (see :func:`reference_prediction`).
    Returns ``(rms, nrms, pi)``."""
    pred, meas, pi = reference_prediction(ident, urdf_text, fixed, refit)
    r, nr = rms_nrms(pred, meas)
    return r, nr, pi
