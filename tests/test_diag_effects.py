"""Model mismatch diagnosis, proven on recordings where one effect is concealed.

A model is identified (mixed method, js2-identify) from a clean simulated session. Then the simulator records an
excitation and a validation trajectory with ONE effect the model does not have. The diagnosis fits its candidate
terms on the excitation and must (1) name the concealed kind on the right joint, (2) recover its physical parameter,
(3) cut the residual on the validation trajectory it never fitted. A clean recording must name nothing.
"""
import json

import numpy as np
import pytest

from fixtures_diag import bench_recording, clean_model, recording


def _diagnose(effects: list[dict]):
    from diagnosis.run import diagnose

    return diagnose(clean_model(), recording(json.dumps(effects)))


CASES = [
    # kind, joint, simulator parameters, check(found effect) -> bool
    ("stribeck", 1, {"velocity": 4.0}, lambda e: e["shape"] == 2.0 and 3.4 < e["velocity"] < 4.6),
    # an exponential hump (shape 1): read as shape 2 on the ladder's grid, its v_s came out 1.4-1.7x the truth;
    # once named it is read again with each shape (Stribeck.refine_grids), and the select rows resolve shape 1
    ("stribeck", 1, {"velocity": 4.0, "shape": 1.0}, lambda e: e["shape"] == 1.0 and 3.4 < e["velocity"] < 4.6),
    # the phase in hil_sim's convention (the ripple acts on the rotor; the drive supplies minus it), so that the
    # found effect simulates back; the simulator's encoder zero is the rotor's
    ("cogging", 2, {"amplitude": 0.004, "periods_per_rev": 2},
     lambda e: e["periods_per_rev"] == 2 and 0.002 < e["amplitude"] < 0.006
     and abs(np.angle(np.exp(1j * e["phase"]))) < 0.3),
    # a fine ripple (18 per motor revolution, as the independent simulator's 12/18/24): at the motor's usual speeds it
    # lies at 30-150 Hz, far above the drive loop's bandwidth, so the current carries it only where the motor turns
    # slowly. Found since the model's friction holds the torque at rest (eq. 2-3): before, the stiction step the
    # torque filter smeared into those slow rows was named a Stribeck on that motor instead (docs/diagnosis.md)
    ("cogging", 2, {"amplitude": 0.004, "periods_per_rev": 18}, lambda e: e["periods_per_rev"] == 18),
    ("payload_change", 5, {"mass": 0.3, "com": [0.05, 0.0, 0.0]},
     lambda e: abs(e["mass"] - 0.3) < 0.03 and abs(e["com"][0] - 0.05) < 0.01),
    # a drift of 25 % of the friction per A^2 at steady state (the independent simulator's drifts raised B by 50-90 %);
    # at 5 % per A^2 its time course changes the FIT residual by 1.5 %: named, but with the time constant at the
    # grid's top (a ramp), not resolved (docs/diagnosis.md)
    ("thermal_drift", 0, {"heating": 5.0, "time_constant": 15.0, "friction_per_kelvin": 0.05},
     lambda e: e["heating"] == 1.0 and 10.0 <= e["time_constant"] <= 25.0
     and 0.2 < e["friction_per_kelvin"] * e["heating"] < 0.3),
    # the same drift heated by the friction power |f w| (gear and bearings), which grows as the friction does
    ("thermal_drift", 0, {"friction_power_heating": 5.0, "time_constant": 20.0, "friction_per_kelvin": 0.05},
     lambda e: e.get("friction_power_heating") == 1.0 and e["heating"] == 0.0 and 14.0 <= e["time_constant"] <= 30.0
     and 0.2 < e["friction_per_kelvin"] < 0.3),
    ("load_dependent_friction", 1, {"coefficient": 0.15}, lambda e: abs(e["coefficient"] - 0.15) < 0.03),
    ("asymmetric_friction", 0, {"negative_scale": 1.5}, lambda e: abs(e["negative_scale"] - 1.5) < 0.1),
    # 2.5:1 between the directions: refused as 'more than 2:1' until stop 30 (AsymmetricFriction.MAX_RATIO)
    ("asymmetric_friction", 0, {"negative_scale": 2.5}, lambda e: abs(e["negative_scale"] - 2.5) < 0.25),
    ("torque_offset", 2, {"offset": 0.03}, lambda e: abs(e["offset"] - 0.03) < 0.006),
    # a shoulder spring whose resonance (7.4 Hz) sits at the torque band's edge: the first-order lag fits it low
    # (1120 N*m/rad, 25 % low), the resonance then inside the band. Named since that is reported, not refused (it was
    # refused until this release and the neighbour's compliance took the residual; docs/diagnosis.md)
    ("joint_elasticity", 1, {"stiffness": 1500.0, "damping": 3.0}, lambda e: 750 < e["stiffness"] < 2250),
    # named since SELECT is the validation trajectory (before, on interleaved blocks of the excitation, the play's
    # fitted scale was far from 1 and it was refused)
    ("backlash", 0, {"width": 0.03, "stiffness": 3000.0, "damping": 3.0}, lambda e: 0.02 <= e["width"] <= 0.04),
]


def _case_id(case) -> str:
    kind, _, params, _ = case.values if hasattr(case, "marks") else case
    return kind + ("_friction_power" if "friction_power_heating" in params else "") + (
        f"_{params['periods_per_rev']}_per_rev" if params.get("periods_per_rev", 0) > 4 else "") + (
        "_shape_1" if params.get("shape") == 1.0 else "")


@pytest.mark.parametrize("kind, joint, params, check", CASES,
                         ids=[_case_id(c) for c in CASES])
def test_concealed_effect_is_located_named_modelled_and_proven(kind, joint, params, check):
    res = _diagnose([{"kind": kind, "joints": [joint], **params}])
    findings = res.findings()
    assert findings, ("nothing found; best candidates: "
                      f"{[s.row(res.rd.joints)['kind'] for s in res.search.rankings_[0][:3]]}")
    top = findings[0]
    assert top["kind"] == kind, f"named {top['kind']} on {top['joint']}, concealed {kind} on joint {joint}"
    assert joint in top["effect"]["joints"]
    assert check(top["effect"]), f"parameters off: {top['effect']} vs simulated {params}"
    # proven on data it did not fit: the validation trajectory's residual on that motor drops
    before, after = np.asarray(top["holdout_rms_before"]), np.asarray(top["holdout_rms_after"])
    motor = joint if kind != "payload_change" else int(np.argmax(before - after))
    assert after[motor] < 0.9 * before[motor]
    assert res.search.score(res.rd, top["band"]) > 0          # report rows: never seen by the search
    assert motor in res.location["flagged"]


def test_terms_are_fitted_on_one_trajectory_and_selected_and_reported_on_another():
    """FIT is the excitation; SELECT and REPORT are disjoint interleaved blocks of the validation trajectory (1 : 2),
    so what the search accepts on is the kind of data the report measures, and the report rows stay unseen."""
    from diagnosis.residual import _trial_rows, residual_data
    from js2spec.log import read_log
    from js2spec.model import load_model

    log = read_log(recording("[]"))
    rd = residual_data(load_model(clean_model()), log)
    exc, val = _trial_rows(log, rd.t, "excitation"), _trial_rows(log, rd.t, "validation")
    for part in (rd.fit_rows, rd.select_rows, rd.holdout_rows):        # labelled: every motor has the same rows
        assert part.shape == rd.mask.shape and (part == part[:, :1]).all()
    fit, sel, rep = rd.fit_rows[:, 0], rd.select_rows[:, 0], rd.holdout_rows[:, 0]
    assert fit.any() and not (fit & ~exc).any()
    assert sel.any() and rep.any() and not ((sel | rep) & ~val).any()
    assert not (sel & rep).any() and not (fit & (sel | rep)).any()
    assert 0.25 < sel.sum() / (sel | rep).sum() < 0.42
    # interleaved: select rows lie between report rows, not all at one end
    assert rd.t[sel].min() < rd.t[rep].max() and rd.t[rep].min() < rd.t[sel].max()
    assert "select and report on the 'validation' trial" in rd.split_note


def test_clean_recording_names_nothing():
    """Nothing named. Since the prediction is filtered once the clean residual is 3-40 % smaller, and the model's
    own identification error on motors 1, 2 and 5 reaches the 12 % select gain of some candidate there: the locator
    points at those motors (``flagged``: where a term would help, with nothing named) and the verdict may say
    ``unexplained``, never a name."""
    res = _diagnose([])
    assert res.accepted == []
    assert res.verdict().startswith(("none", "unexplained"))
    assert all(s.term.reference for s in res.search.references_)


def test_an_offset_on_the_recording_the_model_was_identified_from_is_unexplained_not_named():
    """The recording with a concealed 0.03 N*m offset on motor 3 (named in the case above) as if it were one of the
    model's own inputs (its sha256 in ``inputs``): then the
    constant is the identification's own choice of structure (js2-identify --offsets), reported ``unexplained`` on
    that joint with a note, never named (the clean real TX40 recording's one false name)."""
    import copy
    import dataclasses

    from diagnosis.run import diagnose
    from js2spec.log import file_sha256
    from js2spec.model import load_model

    # as a recording of another day it is named: test_concealed_effect_is_located_named_modelled_and_proven's
    # torque_offset case, on this same recording
    rec = recording(json.dumps([{"kind": "torque_offset", "joints": [2], "offset": 0.03}]))

    mdl = load_model(clean_model())
    raw = copy.deepcopy(mdl.raw)
    raw["inputs"] = list(raw.get("inputs") or []) + [{"path": str(rec), "sha256": file_sha256(rec)}]
    mdl = dataclasses.replace(mdl, raw=raw)
    own = diagnose(mdl, rec)
    assert own.findings() == []
    assert own.verdict().startswith("unexplained")
    unexplained = own.unexplained()
    # first the offset; after it, the refits of the clean model's own friction that test_clean_recording_names_nothing
    # allows
    assert (unexplained[0]["joint_index"], unexplained[0]["reference"]) == (2, "torque_offset")
    assert "js2-identify --offsets" in unexplained[0]["what"]
    assert all(u["reference"] in ("friction_refit", "breakaway_transient") for u in unexplained[1:])
    assert any("identified from this recording" in n for n in own.notes)

def test_found_effect_simulates_back_and_fits_the_recording(tmp_path):
    """'models it': the diagnosed model's effects.yaml is valid hil_sim input, with the recovered parameter."""
    import yaml

    from diagnosis.report import write_outputs
    from hil_sim.effects import parse_effects
    from js2spec.model import load_model

    res = _diagnose([{"kind": "asymmetric_friction", "joints": [0], "negative_scale": 1.5}])
    paths = write_outputs(res, tmp_path)
    effects = yaml.safe_load(paths["effects"].read_text())["effects"]
    parsed = parse_effects(effects, 6, paths["effects"])
    assert parsed[0].kind == "asymmetric_friction" and abs(parsed[0]["negative_scale"] - 1.5) < 0.1
    m = load_model(paths["model"])
    assert m.unmodelled and m.unmodelled[0]["kind"] == "asymmetric_friction"
    assert "asymmetric_friction" in paths["report"].read_text()


def _bench_case(seed: int, tmp_path):
    """Bench case ``seed`` of scripts/bench_diagnose.py (its own trajectory, sample rate and effects), recorded by
    the simulator as the bench does and diagnosed with the test model: (case, DiagnosisResult)."""
    from diagnosis.run import diagnose

    case, rec = bench_recording(seed, tmp_path)
    return case, diagnose(clean_model(), rec)


def test_backlash_on_the_shoulder_reads_as_the_link_resting_on_a_flank(tmp_path):
    """Bench case 0 (scripts/bench_diagnose.py, seed 0: its own trajectory, 1000 Hz, a 0.028 rad play in the
    gravity-loaded shoulder j2, nothing else): the play shows as the link resting b/2 behind the gear on the flank
    its load pushes (BacklashOnFlank), which the simulated impacts of Backlash do not fit (scale 0.08). Named on j2
    alone, with the width about a quarter low (0.021: the elastic column takes part of the offset; docs/diagnosis.md),
    and proven on the report rows."""
    case, res = _bench_case(0, tmp_path)
    assert [(e["kind"], e["joints"]) for e in case["effects"]] == [("backlash", [1])]     # the draw is fixed
    found = res.findings()
    assert [(f["kind"], f["effect"]["joints"]) for f in found] == [("backlash", [1])], res.verdict()
    f = found[0]
    assert f["hyper"] is None and "flank" in f["summary"]                  # the flank reading, not the simulation
    assert 0.7 * case["effects"][0]["width"] <= f["effect"]["width"] <= 1.1 * case["effects"][0]["width"]
    assert f["holdout_gain"] > 0.1                                          # on rows the search never saw


def test_base_axis_play_in_a_limit_cycle_is_read_from_the_gear_oscillation(tmp_path):
    """Bench case 15 (scripts/bench_diagnose.py, seed 15: its own trajectory, 250 Hz, a 0.026 rad play on the
    vertical base axis j1, nothing else): inside the gap the position loop meets the rotor alone and makes the gear
    oscillate across it (a limit cycle at about 23 Hz, 12 mrad peak to peak), and the link, free in the gap, does
    not follow. The simulated impacts (Backlash) cannot follow that chaos and the flank reading (BacklashOnFlank)
    sees nothing on an axis without gravity: named nothing until BacklashRattle, which fits the share of the link's
    torque above the band the motors miss. Named on j1 alone, its width read from the oscillation a lower bound of
    the play (the loop's swing: about half of it here, docs/diagnosis.md), and proven on the report rows."""
    case, res = _bench_case(15, tmp_path)
    assert [(e["kind"], e["joints"]) for e in case["effects"]] == [("backlash", [0])]     # the draw is fixed
    assert case["cycle_hz"] == 250.0
    found = res.findings()
    assert [(f["kind"], f["effect"]["joints"]) for f in found] == [("backlash", [0])], res.verdict()
    f = found[0]
    assert "oscillates above the torque band" in f["summary"]
    width = case["effects"][0]["width"]
    assert 0.3 * width <= f["effect"]["width"] <= width
    assert f["holdout_gain"] > 0.5                                          # on rows the search never saw
    # the headline and the locator score the base motor in the band the play was proven in (unfiltered): not the
    # 7 Hz torque band, where the rattle is filtered away and the finding read as making things worse
    d = res.to_dict()
    assert d["holdout_gain_bands"] == ["wide"] * 6                           # the rattle's torque reaches every motor
    assert not np.any(res.search.predict(res.rd, "low"))                     # and adds nothing in the torque band
    assert d["holdout_gain"] > 0.5
    assert 0 in res.location["flagged"] and "motor 1 (j1): held-out residual (unfiltered)" in res.location["text"]


def test_an_elbow_play_held_on_one_flank_is_reported_as_a_compliance_not_none(tmp_path):
    """Bench case 501 (scripts/bench_diagnose.py, seed 501: its own trajectory, 500 Hz, a 0.053 rad play in the
    elbow j3, nothing else; drawn at stop 36): the validation trajectory (select and report rows) never reverses the
    elbow's torque, so there the play is the link held b/2 behind its gear on one flank; the excitation (fit rows)
    reverses it about a hundred times. No named reading holds on both: the spring's lag (0.053 rad) is more than a
    transmission deflects, the flank reading fitted on the reversals reads the play negative, the simulated play
    fits the reversals and not the flank. Until stop 36 the verdict was ``none`` though the exact play removes 96 %
    of motor 3's residual; now that lag is reported: unexplained, a compliance of j3 (SoftCompliance, scored after
    the ladder on what it leaves), which takes most of motor 3's select residual and holds on the report rows."""
    case, res = _bench_case(501, tmp_path)
    assert [(e["kind"], e["joints"]) for e in case["effects"]] == [("backlash", [2])]     # the draw is fixed
    assert case["cycle_hz"] == 500.0
    assert not res.findings(), res.verdict()
    un = res.unexplained()
    assert [(u["joint_index"], u["reference"]) for u in un] == [(2, "compliance")], un
    assert un[0]["fraction_of_residual"] > 0.5 and un[0]["holdout_gain"] > 0.3
    assert "lags its gear under its load by more than a transmission deflects" in un[0]["what"]
    assert res.verdict().startswith("unexplained:") and "j3" in res.verdict()
    # a last resort: not in the ladder's steps, scored on what is left after them
    from diagnosis.library import SoftCompliance
    last = [any(isinstance(s.term, SoftCompliance) for s in r) for r in res.search.rankings_]
    assert last[-1] and last == sorted(last)            # the ladder's steps first, then the last resort's alone
    assert all(isinstance(s.term, SoftCompliance) for r, k in zip(res.search.rankings_, last) if k for s in r)
