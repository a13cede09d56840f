"""The diagnosis checked in the simulator (``js2-diagnose --replay``): the recording replayed through ``hil_sim`` with
the identified model, then with the model plus the effects found, compared with the recording on the report rows.

The replay is the simulator's own physics (:func:`hil_sim.replay.inverse_replay`: the identified model as a
``Plant``, driven along the recorded motion, with ``hil_sim``'s implementations of the effects), not the search's
regression columns; the motion and the filter are the diagnosis' own (``ResidualData``), so the model-only replay is
the diagnosis' eq. 1 prediction (``tests/test_replay.py`` checks they agree to 1e-9 N m).
"""
from __future__ import annotations

import numpy as np

from hil_sim.replay import forward_replay, inverse_replay, model_holds_unclipped, model_plant, rms_per_joint
from js2spec.effects import EFFECT_KINDS

from .residual import part_rows
from .run import DiagnosisResult

ROWS = ("report rows (never seen by the search), moving samples of each motor, motor side, in the torque band "
        "(filtered like the measured torque)")


def replay_torques(res: DiagnosisResult, effects: list[dict]) -> np.ndarray:
    """Motor torques (N, n) the simulator needs along the recording's motion with the model plus ``effects``,
    offsets included, filtered like the measured torque (the diagnosis' ``tau_meas``)."""
    rd = res.rd
    drives = _drives(res)
    plant = model_plant(res.model, drives, effects, effects_source="diagnosis findings")
    off = res.model.torque_offset
    off_motor = off @ rd.K if rd.torque_side == "joint" else off       # offsets on the log's side -> motor side
    # at rest the friction holds the recorded torque up to f_s, as the diagnosis predicts (hold_at_rest)
    tau = inverse_replay(plant, rd.t, rd.q_motor, rd.dq_motor, rd.ddq_motor, tau_recorded=rd.tau_meas_raw - off_motor,
                         v_rest=rd.min_speed_motor, hold_unclipped=model_holds_unclipped(res.model)).tau_motor
    tau = tau + off_motor
    return rd.signals.filter_like_torque(np.nan_to_num(tau))


def forward_positions(res: DiagnosisResult, effects: list[dict], bandwidth_hz: float = 5.0):
    """Forward replay (:func:`hil_sim.replay.forward_replay`): the plant under the recorded motor torque (offsets
    removed) plus a tracking term at ``bandwidth_hz``; returns (simulated motor angles (N, n), tracking torque)."""
    rd = res.rd
    plant = model_plant(res.model, _drives(res), effects, effects_source="diagnosis findings")
    off = res.model.torque_offset
    tau = rd.tau_meas - (off @ rd.K if rd.torque_side == "joint" else off)
    fr = forward_replay(plant, rd.t, rd.q_motor, rd.dq_motor, tau, runs=rd.signals.runs, bandwidth_hz=bandwidth_hz)
    return fr.q_motor, fr.tau_pd


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
    rows = part_rows(rd.holdout_rows, rd.n) & rd.mask
    before = rms_per_joint(rd.tau_meas - tau0, rows)
    after = rms_per_joint(rd.tau_meas - tau1, rows)
    scale = rms_per_joint(rd.tau_meas - tau0, part_rows(rd.fit_rows, rd.n) & rd.mask)
    w = np.where(np.isfinite(scale) & (scale > 0), 1.0 / np.where(scale > 0, scale, 1.0) ** 2, 0.0)
    ok = np.isfinite(before) & np.isfinite(after)
    den = float(np.sum(w[ok] * before[ok] ** 2))
    gain = 1.0 - float(np.sum(w[ok] * after[ok] ** 2)) / den if den > 0 else None
    arrays = {"tau_model": tau0, "tau_effects": tau1, "rows": rows}
    fwd = {}
    report = part_rows(rd.holdout_rows, rd.n) & rd.signals.keep[:, None]     # (N, n): each motor's report rows
    for key, eff in (("model", []), ("model_effects", sim)):
        if key == "model_effects" and not sim:
            fwd[key] = fwd["model"]
            continue
        q_sim, tau_pd = forward_positions(res, eff)
        err = np.where(np.isfinite(q_sim), (rd.q_motor - q_sim) @ rd.K.T, np.nan)
        fwd[key] = {"position_rms": rms_per_joint(err, report).tolist(),
                    "tracking_torque_rms": rms_per_joint(tau_pd, report).tolist(),
                    "followed": (float(np.mean(np.isfinite(q_sim[report.any(axis=1), 0]))) if report.any()
                                 else 0.0)}
    return {"mode": "inverse dynamics: the recorded motion prescribed, the simulator's torque compared",
            "rows": ROWS, "joints": rd.joints,
            "effects": sim, "not_simulated": skipped,
            "rms_model": before.tolist(), "rms_model_effects": after.tolist(),
            "drop": [None if not (np.isfinite(b) and b > 0) else float(1 - a / b) for a, b in zip(after, before)],
            "gain": gain,
            "gain_definition": "1 - sum of squared (recording - simulation) with the effects / without, each motor "
                               "scaled by its model-only gap on the fit rows, report rows only",
            "forward": {"what": "the plant under the recorded motor torque plus a tracking term M_z(theta) (w^2 e + "
                                "2 w e_dot), w = 2 pi 5 Hz, from the recording's state at the start of each run; "
                                "joint angles (rad, joint side) and the tracking torque (N*m, motor side) on the "
                                "report rows; 'followed': share of them before the plant left the recording by 1 rad",
                        "model": fwd["model"], "model_effects": fwd["model_effects"]},
            "agreement_with_diagnosis_prediction": float(np.nanmax(np.abs(
                (tau0 - rd.tau_pred)[rd.mask]))) if rd.mask.any() else None}, arrays
