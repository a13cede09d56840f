"""The diagnosis checked in the simulator (``js2-diagnose --replay``): the recording replayed through ``hil_sim`` with
the identified model, then with the model plus the effects found, compared with the recording on the report rows.

The replay is the simulator's own physics (:func:`hil_sim.replay.inverse_replay`: the identified model as a
``Plant``, driven along the recorded motion, with ``hil_sim``'s implementations of the effects), not the search's
regression columns; the motion and the filter are the diagnosis' own (``ResidualData``), so the model-only replay is
the diagnosis' eq. 1 prediction (``tests/test_replay.py`` checks they agree to 1e-9 N m).
"""
from __future__ import annotations

import numpy as np

from hil_sim.replay import inverse_replay, model_offsets, model_plant, rms_per_joint
from js2spec.effects import EFFECT_KINDS

from .run import DiagnosisResult

ROWS = ("report rows (never seen by the search), moving samples of each motor, motor side, in the torque band "
        "(filtered like the measured torque)")


def replay_torques(res: DiagnosisResult, effects: list[dict]) -> np.ndarray:
    """Motor torques (N, n) the simulator needs along the recording's motion with the model plus ``effects``,
    offsets included, filtered like the measured torque (the diagnosis' ``tau_meas``)."""
    rd = res.rd
    drives = _drives(res)
    plant = model_plant(res.model, drives, effects, effects_source="diagnosis findings")
    tau = inverse_replay(plant, rd.t, rd.q_motor, rd.dq_motor, rd.ddq_motor).tau_motor
    off = model_offsets(res.model)
    tau = tau + (off @ rd.K if rd.torque_side == "joint" else off)      # offsets on the log's side -> motor side
    return rd.signals.filter_like_torque(np.nan_to_num(tau))


def _drives(res: DiagnosisResult):
    """The recording's drives (its transmission and torque side), read once."""
    if "drives" not in res.rd.extra:
        from js2spec.log import read_log

        res.rd.extra["drives"] = read_log(res.log_path).drives
    return res.rd.extra["drives"]


def replay_section(res: DiagnosisResult) -> tuple[dict, dict]:
    """``diagnosis.json`` ``replay``: per motor RMS of recording - simulation on the report rows, with the model
    alone and with the found effects; ``gain`` weighs each motor by its model residual on the fit rows (the
    diagnosis' own ``holdout_gain`` weighting). Also returns the torques for the report's figure."""
    rd = res.rd
    found = res.sim_effects()
    sim = [e for e in found if e.get("kind") in EFFECT_KINDS]
    skipped = [e.get("kind") for e in found if e.get("kind") not in EFFECT_KINDS]
    tau0 = replay_torques(res, [])
    tau1 = replay_torques(res, sim) if sim else tau0
    rows = rd.holdout_rows[:, None] & rd.mask
    before = rms_per_joint(rd.tau_meas - tau0, rows)
    after = rms_per_joint(rd.tau_meas - tau1, rows)
    scale = rms_per_joint(rd.tau_meas - tau0, rd.fit_rows[:, None] & rd.mask)
    w = np.where(np.isfinite(scale) & (scale > 0), 1.0 / np.where(scale > 0, scale, 1.0) ** 2, 0.0)
    ok = np.isfinite(before) & np.isfinite(after)
    den = float(np.sum(w[ok] * before[ok] ** 2))
    gain = 1.0 - float(np.sum(w[ok] * after[ok] ** 2)) / den if den > 0 else None
    arrays = {"tau_model": tau0, "tau_effects": tau1, "rows": rows}
    return {"mode": "inverse dynamics: the recorded motion prescribed, the simulator's torque compared",
            "rows": ROWS, "joints": rd.joints,
            "effects": sim, "not_simulated": skipped,
            "rms_model": before.tolist(), "rms_model_effects": after.tolist(),
            "drop": [None if not (np.isfinite(b) and b > 0) else float(1 - a / b) for a, b in zip(after, before)],
            "gain": gain,
            "gain_definition": "1 - sum of squared (recording - simulation) with the effects / without, each motor "
                               "scaled by its model-only gap on the fit rows, report rows only",
            "agreement_with_diagnosis_prediction": float(np.nanmax(np.abs(
                (tau0 - rd.tau_pred)[rd.mask]))) if rd.mask.any() else None}, arrays
