"""js2-diagnose on real recordings nobody on the team made (KUKA LWR4+, ../shared/data/real/kuka_lwr4: 200 Hz, joint
torque sensors, K = I, a gear-1 arm, no trial labels), with a model from ``js2-identify --method simultaneous``
(``friction.static`` null): the five real-data blockers of issue 11, the clean recordings, the payload protocol
(scripts/prove_diagnosis_real.py) and the three-part honest split. Skipped when the data folder is absent."""
from __future__ import annotations

import json

import numpy as np
import pytest

from fixtures_id_sim import REAL, prove_diagnosis_real

pytestmark = pytest.mark.skipif(not (REAL / "kuka_lwr4").is_dir(),
                                reason=f"real-arm recordings not found at {REAL} (CI has ../shared/data/real)")

prove = prove_diagnosis_real()


README_MASS = {2: 1.961, 1: 1.991, 3: 1.984}     # kg found for the 2 kg payload (README, docs/diagnosis.md; 2 %)


@pytest.fixture(scope="module")
def kuka(kuka_diag):
    """The imported recordings and the plain js2-identify model (conftest: made once per session)."""
    return kuka_diag


@pytest.fixture(scope="module")
def payload_200hz(kuka):
    log = prove.payload_log(REAL, kuka["work"] / "kuka_2_payload.mcap")
    return log, prove.diagnose_cli(kuka["model"], log, kuka["work"] / "diag_payload")


def test_model_from_the_simultaneous_method_is_accepted(kuka):
    from js2spec.model import load_model

    m = load_model(kuka["model"])
    assert m.raw["method_key"] == "simultaneous"
    assert np.all(np.isnan(m.friction_static))           # null in model.yaml: no static test in these recordings
    assert np.all(np.isfinite(m.friction_coulomb))


def test_joint_side_torques_with_k_identity_and_gear_one_min_speed(kuka):
    from diagnosis.residual import residual_data
    from js2spec.log import read_log
    from js2spec.model import load_model

    log = read_log(kuka["logs"][0])
    rd = residual_data(load_model(kuka["model"]), log)
    assert rd.torque_side == "joint" and np.allclose(rd.K, np.eye(7))
    np.testing.assert_allclose(rd.min_speed_motor, 0.01)          # 0.01 rad/s at the joint = at the "motor" (K = I)
    keep = rd.signals.keep
    speed = np.abs(np.nan_to_num(rd.dq_motor[:, 1]))
    # the shoulder of a gear-1 arm keeps its moving samples (the old motor-side 1 rad/s default dropped most)
    assert rd.mask[:, 1].sum() >= 0.9 * (keep & (speed > 0.01)).sum()
    assert (keep & (speed >= 1.0)).sum() < 0.5 * rd.mask[:, 1].sum()
    # joint torques were predicted on their side: the residual is small against the torque itself (a sane model)
    m = rd.mask[:, 1]
    assert np.sqrt(np.mean(rd.residual[m, 1] ** 2)) < 0.5 * np.sqrt(np.mean(rd.tau_meas[m, 1] ** 2))


def test_min_speed_is_joint_side_for_a_geared_arm():
    """The same --min-speed on the simulated 1:50-1:100 arm: motor i's threshold is 0.01 / max_j |K_ji| rad/s."""
    from diagnosis.residual import residual_data
    from fixtures_diag import clean_model, recording
    from js2spec.log import read_log
    from js2spec.model import load_model

    log = read_log(recording("[]"))
    rd = residual_data(load_model(clean_model()), log)
    K = np.asarray(log.drives.gear_ratio_matrix, float)
    np.testing.assert_allclose(rd.min_speed_motor, 0.01 / np.abs(K).max(axis=0))
    assert rd.min_speed_motor[0] == pytest.approx(1.0, rel=0.01)     # 1:100 shoulder: 1 rad/s at the motor


def test_validation_only_recording_gets_a_documented_time_split(kuka):
    from diagnosis.residual import residual_data
    from js2spec.log import read_log
    from js2spec.model import load_model

    log_path = prove.payload_log(REAL, kuka["work"] / "kuka_2_validation_only.mcap", mass=0.0,
                                 trials=[("validation", 0.0, 100.0)])
    log = read_log(log_path)
    assert log.trials() == ["validation"]
    rd = residual_data(load_model(kuka["model"]), log)
    assert "time split" in rd.split_note and "'validation' trial is the whole recording" in rd.split_note
    fit, sel, rep = rd.fit_rows.any(axis=1), rd.select_rows.any(axis=1), rd.holdout_rows.any(axis=1)
    assert fit.sum() > 1000 and sel.sum() > 400 and rep.sum() > 800
    for j in range(rd.n):                                            # per motor: no row in two parts
        fit, sel, rep = rd.fit_rows[:, j], rd.select_rows[:, j], rd.holdout_rows[:, j]
        assert not (fit & sel).any() and not (fit & rep).any() and not (sel & rep).any()
        assert rd.t[rep].min() > rd.t[fit | sel].max()               # the report part is the end of the recording


@pytest.mark.parametrize("which", [1, 2, 3])
def test_clean_real_recordings_name_no_effect(kuka, which):
    lg = next(p for p in kuka["logs"] if p.stem.endswith(str(which)))
    d = prove.diagnose_cli(kuka["model"], lg, kuka["work"] / f"diag_{lg.stem}")
    assert d["findings"] == [], (lg.name, d["verdict"])
    assert d["verdict"].startswith(("none", "unexplained"))
    for u in d["unexplained"]:
        assert u["joint"] in d["location"]["motors"][u["joint_index"]]["joint"]
        assert u["frequency_band"] in d["location"]["motors"][u["joint_index"]]["frequency_bands"]   # where, in Hz
    for m in d["location"]["motors"]:
        assert sum(m["frequency_bands"].values()) == pytest.approx(1.0)


@pytest.fixture(scope="module")
def tx40(tmp_path_factory):
    """The TX40 recording imported, identified and diagnosed with the plain commands (prove step 6)."""
    if not (REAL / "staubli_tx40").is_dir():
        pytest.skip(f"{REAL / 'staubli_tx40'} not found")
    work = tmp_path_factory.mktemp("tx40")
    return work, prove.tx40_clean(REAL, work)


def test_clean_real_tx40_recording_names_no_effect(tx40):
    """A second arm (5 kHz motor currents, coupled wrist, 9 s): js2-import, the plain js2-identify and js2-diagnose
    on the same recording. Its identification leaves the offsets out (cross-validation) and motor 6 carries
    +0.006 N*m against it: reported unexplained (the model's own data), not named; no thermal drift is looked for
    in 9 s."""
    tmp_path, d = tx40
    assert d["findings"] == [], d["verdict"]
    assert d["verdict"].startswith(("none", "unexplained"))
    assert any("identified from this recording" in n for n in d["notes"])
    assert any("thermal drift not looked for" in n for n in d["notes"])
    assert [u["joint"] for u in d["unexplained"] if u["reference"] == "torque_offset"] == ["joint_6"]
    # the same recording imported again: another file (its metadata differs), the same data (data_sha256)
    from identification.examples.real_arms import import_tx40
    from js2spec.log import read_log

    again = import_tx40(REAL, tmp_path / "again.mcap", source_text="imported again")
    first, second = read_log(tmp_path / "tx40.mcap"), read_log(again)
    assert first.sha256 != second.sha256 and first.data_sha256 == second.data_sha256
    d2 = prove.diagnose_cli(tmp_path / "model", again, tmp_path / "diag_again")
    assert d2["findings"] == [] and any("identified from this recording" in n for n in d2["notes"])


README_TX40_MASS = 0.993       # kg found for TX40_PAYLOAD_MASS (README, docs/diagnosis.md; 2 %)


def test_payload_added_to_the_real_tx40_is_found_and_its_own_offset_stays_unexplained(tx40):
    """The payload protocol on the second arm (prove step 7): 1 kg on the TX40's hand, its torque carried to the
    motors through the coupled wrist. The payload is named on the hand within 10 %, and nothing else: the
    +0.006 N*m on motor 6 is in this recording because it is in the model's own (the file the model was identified
    from, still where model.yaml says), so it is reported unexplained with that reason, not named as before."""
    work, _ = tx40
    log = prove.tx40_payload_log(REAL, work / "tx40_payload.mcap")
    d = prove.diagnose_cli(work / "model", log, work / "diag_payload")
    assert [(f["kind"], f["joint"]) for f in d["findings"]] == [("payload_change", "joint_6")], d["verdict"]
    mass = d["findings"][0]["effect"]["mass"]
    assert mass == pytest.approx(prove.TX40_PAYLOAD_MASS, rel=0.10)
    assert mass == pytest.approx(README_TX40_MASS, rel=0.02)
    own = [u for u in d["unexplained"] if u["reference"] == "torque_offset"]
    assert [u["joint"] for u in own] == ["joint_6"]
    import re

    carried = re.search(r"tx40\.mcap, the model's own, carries ([+-][0-9.e-]+) \+- ([0-9.e-]+) N\*m", own[0]["what"])
    assert carried and round(float(carried.group(1)), 3) == 0.006            # the README's +0.006 N*m on motor 6
    # the model's recording moved away: the offset is what the new recording shows against the model, named
    (work / "tx40.mcap").rename(work / "moved.mcap")
    try:
        d2 = prove.diagnose_cli(work / "model", log, work / "diag_payload_moved")
    finally:
        (work / "moved.mcap").rename(work / "tx40.mcap")
    assert ("torque_offset", "joint_6") in [(f["kind"], f["joint"]) for f in d2["findings"]]


def test_a_short_piece_of_a_real_recording_names_nothing(tx40):
    """The TX40 recording cut at 1 MB (2.5 s of it, recovered up to its last complete chunk): fit, select and report
    are a few blocks of one motion, and the search had named an offset and an asymmetric friction that together made
    the report rows 20 % worse. Under MIN_NAMING_SPAN_S nothing is named; what passed is reported unexplained, with
    the reason."""
    from diagnosis.run import MIN_NAMING_SPAN_S

    from identification.examples.real_arms import TX40_RATE, load_tx40, write_tx40

    work, _ = tx40
    rec = load_tx40(REAL)
    keep = 12726                  # what a cut at 1 MB recovers: 2.545 s of the excitation (the same samples here,
    rec.t, rec.position, rec.torque = rec.t[:keep], rec.position[:keep], rec.torque[:keep]   # cut by samples)
    piece = write_tx40(rec, REAL, work / "piece.mcap", trials=[("excitation", 0.0, keep / TX40_RATE)])
    d = prove.diagnose_cli(work / "model", piece, work / "diag_piece")
    assert d["findings"] == [] and d["verdict"].startswith(("unexplained", "none")), d["verdict"]
    assert any(n.startswith("nothing named: the recording spans 2.5") for n in d["notes"])


def test_an_effect_in_a_recording_under_5_s_is_reported_not_named(kuka, tmp_path):
    """The demotion itself: kuka_2 with a 0.8 N*m torque offset added (named alone on the whole recording, step 8),
    cut to its first 4 s: the search passes the offset, and torque offsets on three joints nothing was added to
    (lwr_4, lwr_5, lwr_6) -- why nothing is named from so short a recording; all four are reported unexplained
    with the reason."""
    from diagnosis.run import MIN_NAMING_SPAN_S
    from identification import importer as im
    from identification.examples.real_arms import write_kuka
    from js2spec.log import read_log

    full = read_log(prove.effect_log(REAL, tmp_path / "full.mcap", "torque_offset", kuka["model"]))
    fb = full.feedback
    keep = fb.t - fb.t[0] < 4.0
    rec = im.Recording(t=fb.t[keep], position=fb.motor_position[keep], torque=fb.torque[keep], current=None,
                       source="kuka_2 + offset, first 4 s")
    piece = write_kuka(rec, REAL, tmp_path / "piece.mcap")
    d = prove.diagnose_cli(kuka["model"], piece, tmp_path / "d")
    assert d["findings"] == [], d["verdict"]
    assert any(n.startswith("nothing named: the recording spans 4") for n in d["notes"])
    short = [u for u in d["unexplained"] if "too short to name an effect" in u["what"]]
    demoted = [(u["reference"], u["joint_index"]) for u in short]
    # the added offset among them, and what 4 s also "showed": offsets on three joints nothing was added to
    assert ("torque_offset", 2) in demoted and len(demoted) == 4, demoted
    assert all(f"(at least {MIN_NAMING_SPAN_S:g} s)" in u["what"] for u in short)


@pytest.mark.parametrize("kind", list(prove.REAL_EFFECTS))
def test_an_effect_added_to_a_real_recording_is_named_on_its_joint(kuka, tmp_path, kind):
    """Prove step 8: kuka_2 (real noise, real model error) with one effect's torque added along the recorded motion,
    in hil_sim's form of that kind: named on its joint with the plain command. The asymmetric friction (scale 1.5
    on joint 4) had been read as a torque offset: its columns lacked the viscous column of the friction refit it
    must beat, and this recording's joint 4 refits its viscous friction by -0.75 N*m*s/rad."""
    j = prove.REAL_EFFECTS[kind][0]
    log = prove.effect_log(REAL, tmp_path / f"kuka_2_{kind}.mcap", kind, kuka["model"])
    d = prove.diagnose_cli(kuka["model"], log, tmp_path / "d")
    named = [(f["kind"], f["joint_index"]) for f in d["findings"]]
    assert (kind, j) in named, d["verdict"]
    f = next(f for f in d["findings"] if f["kind"] == kind)
    if kind == "asymmetric_friction":
        # 1.41 until the findings were estimated together (stop 24): the refit beside it had kept part of it
        assert f["effect"]["negative_scale"] == pytest.approx(1.56, abs=0.03)
    elif kind == "stribeck":
        assert f["effect"]["velocity"] == pytest.approx(0.15, rel=0.1)
    elif kind == "cogging":
        assert f["effect"]["periods_per_rev"] == 36 and f["effect"]["amplitude"] == pytest.approx(0.6, rel=0.15)
    elif kind == "load_dependent_friction":
        assert f["effect"]["coefficient"] == pytest.approx(0.05, rel=0.1)
    else:
        assert f["effect"]["offset"] == pytest.approx(0.8, rel=0.05)


def test_payload_added_to_a_real_recording_is_found_within_10_percent(payload_200hz):
    log, d = payload_200hz
    pay = [f for f in d["findings"] if f["kind"] == "payload_change"]
    assert pay, d["verdict"]
    f = pay[0]
    assert f["joint"] == "lwr_6_joint"                                # the hand
    assert f["effect"]["mass"] == pytest.approx(prove.PAYLOAD_MASS, rel=0.10)
    assert f["effect"]["mass"] == pytest.approx(README_MASS[2], rel=0.02)   # the README's figure
    assert np.linalg.norm(np.subtract(f["effect"]["com"], prove.PAYLOAD_COM)) < 0.04
    assert f["holdout_gain"] > 0.3                                     # on the report rows the search never saw
    assert [x["kind"] for x in d["findings"]].count("payload_change") == 1


def test_any_sample_rate_100hz_payload(kuka, tmp_path):
    from diagnosis.cli import main

    log = prove.payload_log(REAL, tmp_path / "kuka_2_payload_100hz.mcap", decimate=2)
    assert main([str(kuka["model"]), str(log), "-o", str(tmp_path / "d"), "-q"]) == 0
    d = json.loads((tmp_path / "d" / "diagnosis.json").read_text())
    assert d["sample_rate_hz"] == 100.0 and d["filters_hz"]["velocity"] == pytest.approx(40.0)
    assert any(n.startswith("sampled at 100 Hz: a gear's oscillation") for n in d["notes"]), d["notes"]
    pay = [f for f in d["findings"] if f["kind"] == "payload_change"]
    assert pay and pay[0]["effect"]["mass"] == pytest.approx(prove.PAYLOAD_MASS, rel=0.10)


def test_report_rows_never_reach_the_search(kuka):
    """Honest proof: garbage on the report rows changes the reported gains, never what the search accepts."""
    from diagnosis.residual import residual_data
    from diagnosis.search import MismatchSearch
    from js2spec.log import read_log
    from js2spec.model import load_model

    log = read_log(prove.payload_log(REAL, kuka["work"] / "kuka_3_payload_honest.mcap", which=3))
    rd = residual_data(load_model(kuka["model"]), log)
    kinds = ["payload_change", "stribeck", "asymmetric_friction"]
    a = MismatchSearch(kinds=kinds).fit(rd)
    gain_a = a.score(rd)
    rng = np.random.default_rng(0)
    rep = rd.holdout_rows
    rd.tau_meas[rep] += rng.normal(0, 5.0, rd.tau_meas[rep].shape)
    b = MismatchSearch(kinds=kinds).fit(rd)
    assert [(s.fitted.kind, s.fitted.joint) for s in a.accepted_] == [(s.fitted.kind, s.fitted.joint)
                                                                      for s in b.accepted_]
    assert a.accepted_ and np.allclose(a.accepted_[0].fitted.coef, b.accepted_[0].fitted.coef)
    assert b.score(rd) != gain_a


@pytest.mark.parametrize("which", [1, 3])
def test_payload_spread_on_the_other_recordings(kuka, which):
    """The same 2 kg on kuka_1 (the model's own recording) and kuka_3: named on the hand within 10 % (kuka_3: on the
    hand although the select rows prefer the same point on lwr_6_link, docs/diagnosis.md). Nothing else is named:
    up to stop 28 kuka_3 also got a backlash on lwr_3_joint (a soft simulated contact beside a negative
    compliance, -0.0042 +- 0.0002 rad/(N*m), now refused by ``Backlash.effect``)."""
    log = prove.payload_log(REAL, kuka["work"] / f"kuka_{which}_payload.mcap", which=which)
    d = prove.diagnose_cli(kuka["model"], log, kuka["work"] / f"diag_payload_{which}")
    assert [f["kind"] for f in d["findings"]] == ["payload_change"], d["verdict"]
    pay = [f for f in d["findings"] if f["kind"] == "payload_change"]
    assert pay and pay[0]["joint"] == "lwr_6_joint", d["verdict"]
    assert pay[0]["effect"]["mass"] == pytest.approx(prove.PAYLOAD_MASS, rel=0.10)
    if which in README_MASS:
        assert pay[0]["effect"]["mass"] == pytest.approx(README_MASS[which], rel=0.02)   # the README's figure


def test_prediction_carries_the_exported_offsets_and_sqrt_viscous_friction(kuka, tmp_path):
    """The prediction is the exported model's: ``torque_offset`` (of the physically consistent parameters the URDF
    holds, not the base ``off_k`` of the unconstrained fit) and ``friction.sqrt_viscous`` when present."""
    import shutil

    import yaml

    from diagnosis.residual import residual_data
    from js2spec.log import read_log
    from js2spec.model import load_model

    log = read_log(kuka["logs"][0])
    m0 = load_model(kuka["model"])
    rd0 = residual_data(m0, log)
    # the model's own recording: no shoulder offset left over (the base off_2 was 2.7 N*m away from the export's)
    rep = rd0.mask[:, 1] & rd0.holdout_rows[:, 1]
    assert abs(np.mean(rd0.residual[rep, 1])) < 0.5
    d = dict(m0.raw)
    d["torque_offset"] = [v + (1.0 if k == 2 else 0.0) for k, v in enumerate(d["torque_offset"])]
    d["friction"] = dict(d["friction"], sqrt_viscous=[0.0, 0.0, 0.0, 0.0, 0.5, 0.0, 0.0])
    for f in kuka["model"].iterdir():
        if f.name != "model.yaml" and f.is_file():
            shutil.copy(f, tmp_path / f.name)
    (tmp_path / "model.yaml").write_text(yaml.safe_dump(d))
    rd1 = residual_data(load_model(tmp_path), log)
    diff = rd1.tau_pred_raw - rd0.tau_pred_raw
    # where a joint is at rest its friction holds the recorded torque (up to f_c: no f_s from this method), so an
    # offset changes the held friction there, not the prediction: compare rows where every joint moves
    ok = np.isfinite(diff).all(axis=1) & ~rd0.at_rest.any(axis=1)
    assert ok.sum() > 1000
    v = rd0.dq_motor[ok, 4]                                    # K = I: joint speed
    np.testing.assert_allclose(diff[ok, 2], 1.0, atol=1e-9)
    np.testing.assert_allclose(diff[ok, 4], 0.5 * np.sign(v) * np.sqrt(np.abs(v)), atol=1e-9)
    np.testing.assert_allclose(diff[ok][:, [0, 1, 3, 5, 6]], 0.0, atol=1e-9)


def test_one_session_over_several_files(kuka, tmp_path):
    """`js2-diagnose MODEL LOG LOG -o DIR`: the kuka_2 payload recording cut in two files is diagnosed as one session
    (each file filtered on its own) and the payload is still found on the hand within 10 %."""
    parts = [prove.payload_log(REAL, tmp_path / f"part{k}.mcap", part=p) for k, p in
             enumerate(((0.0, 0.5), (0.5, 1.0)))]
    from diagnosis.cli import main

    assert main([str(kuka["model"]), *map(str, parts), "-o", str(tmp_path / "d"), "-q"]) == 0
    d = json.loads((tmp_path / "d" / "diagnosis.json").read_text())
    assert d["recordings"] == [str(p) for p in parts]
    assert any("one session over 2 files" in n for n in d["notes"])
    pay = [f for f in d["findings"] if f["kind"] == "payload_change"]
    assert pay and pay[0]["joint"] == "lwr_6_joint", d["verdict"]
    assert pay[0]["effect"]["mass"] == pytest.approx(prove.PAYLOAD_MASS, rel=0.10)


def test_a_payload_within_the_models_own_uncertainty_is_no_finding(kuka, payload_200hz):
    """PayloadChange.UNCERTAINTY_QUANTILE: clean kuka_2 holds a small hand reading of its own (about -0.034 kg, a
    first moment of -0.014 kg m) that the 12 % floor passed once another effect was explained. Its change of the
    model's base parameters is within their standard errors (chi-square under the 99 % point), so it is refused
    with that reason; the 2 kg payload's is thousands of times over it and is named."""
    from diagnosis.library import PayloadChange, payload_within_model
    from diagnosis.residual import residual_data
    from js2spec.log import read_log
    from js2spec.model import load_model

    mdl = load_model(kuka["model"])
    lg = next(p for p in kuka["logs"] if p.stem.endswith("2"))
    rd = residual_data(mdl, read_log(lg))
    own = np.array([-0.034, 0.0019, -0.0137, -0.0026])        # m, m c_x, m c_y, m c_z on lwr_7_link (kg, kg m)
    c2, dof, limit = payload_within_model(rd, 6, own)
    assert dof > 4 and c2 < limit
    eff, _, ok, why = PayloadChange().effect(rd, 6, None, own, np.full(4, 1e-4))
    assert not ok and "a mass taken off the link" in why          # negative: refused for its sign by default
    rd.extra["payload_removed"] = True                            # js2-diagnose --payload-removed: the uncertainty
    eff, _, ok, why = PayloadChange().effect(rd, 6, None, own, np.full(4, 1e-4))
    assert not ok and "within the model's own uncertainty" in why and f"over {dof}" in why
    _, d = payload_200hz
    found = next(f for f in d["findings"] if f["kind"] == "payload_change")
    coef = np.r_[found["effect"]["mass"], found["effect"]["mass"] * np.asarray(found["effect"]["com"])]
    c2, _, limit = payload_within_model(rd, 6, coef)
    assert c2 > 100 * limit


def test_the_aliased_ripple_rule_never_reaches_the_kuka_recordings(kuka):
    """Stop 33's Cogging.sampled zeroes rows where p |w| / 2 pi is above half the sample rate. The KUKA motors (joint
    side, K = I) turn at under 2 rad/s: for every period count of the grid (up to 96) it zeroes nothing, at 200 Hz or read at
    100 Hz, so the real-data bench's and the proof's readings on them are the numbers they were (README)."""
    from diagnosis.library import Cogging
    from diagnosis.residual import residual_data
    from js2spec.log import read_log
    from js2spec.model import load_model

    model = load_model(kuka["model"])
    for path in kuka["logs"]:
        rd = residual_data(model, read_log(path))
        for j in range(rd.n):
            grid = Cogging().grid(rd, j)
            # up to 96 per revolution, less where the fit rows cover under 3 periods with the ripple in the torque
            # band (stop 46: Cogging.in_band_cover)
            assert grid and max(grid) <= 96
            assert min(Cogging().in_band_cover(rd, j, grid)) >= Cogging.MIN_IN_BAND_PERIODS
            w = np.abs(np.nan_to_num(rd.dq_motor[:, j])).max()
            assert w < 2.0 and max(grid) * w / (2 * np.pi) < 100.0 / 2
            assert np.all(Cogging.sampled(rd, j, max(grid)) == 1.0)
