"""js2-diagnose on real recordings nobody on the team made (KUKA LWR4+, ../shared/data/real/kuka_lwr4: 200 Hz, joint
torque sensors, K = I, a gear-1 arm, no trial labels), with a model from ``js2-identify --method simultaneous``
(``friction.static`` null): the five real-data blockers of issue 11, the clean recordings, the payload protocol
(scripts/prove_diagnosis_real.py) and the three-part honest split. Skipped when the data folder is absent."""
from __future__ import annotations

import importlib.util
import json

import numpy as np
import pytest

from fixtures_id_sim import REAL, REPO

pytestmark = pytest.mark.skipif(not (REAL / "kuka_lwr4").is_dir(),
                                reason=f"real-arm recordings not found at {REAL} (CI has ../shared/data/real)")

_spec = importlib.util.spec_from_file_location("prove_diagnosis_real", REPO / "scripts" / "prove_diagnosis_real.py")
prove = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(prove)


@pytest.fixture(scope="module")
def kuka(tmp_path_factory):
    work = tmp_path_factory.mktemp("kuka_diag")
    logs = prove.import_logs(REAL, work)
    model = prove.identify(logs[0], work / "model")
    return {"work": work, "logs": logs, "model": model}


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
    fit, sel, rep = rd.fit_rows, rd.select_rows, rd.holdout_rows
    assert fit.sum() > 1000 and sel.sum() > 400 and rep.sum() > 800
    assert not (fit & sel).any() and not (fit & rep).any() and not (sel & rep).any()
    assert rd.t[rep].min() > rd.t[fit | sel].max()                   # the report part is the end of the recording


KUKA3_FALSE_NAME = ("known failure since the issue-10 identification changes: with the exported KUKA model, kuka_3's "
                     "refit-null residual on lwr_2 is cut by just over the 25 % margin by load-dependent friction, "
                     "which is then named (a false name); the payload added to kuka_3 is found (1.86 kg) but placed "
                     "on lwr_5's link, not the hand")


@pytest.mark.parametrize("which", [1, 2, pytest.param(3, marks=pytest.mark.xfail(reason=KUKA3_FALSE_NAME))])
def test_clean_real_recordings_name_no_effect(kuka, which):
    lg = next(p for p in kuka["logs"] if p.stem.endswith(str(which)))
    d = prove.diagnose_cli(kuka["model"], lg, kuka["work"] / f"diag_{lg.stem}")
    assert d["findings"] == [], (lg.name, d["verdict"])
    assert d["verdict"].startswith(("none", "unexplained"))
    for u in d["unexplained"]:
        assert u["joint"] in d["location"]["motors"][u["joint_index"]]["joint"]


def test_payload_added_to_a_real_recording_is_found_within_10_percent(payload_200hz):
    log, d = payload_200hz
    pay = [f for f in d["findings"] if f["kind"] == "payload_change"]
    assert pay, d["verdict"]
    f = pay[0]
    assert f["joint"] == "lwr_6_joint"                                # the hand
    assert f["effect"]["mass"] == pytest.approx(prove.PAYLOAD_MASS, rel=0.10)
    assert np.linalg.norm(np.subtract(f["effect"]["com"], prove.PAYLOAD_COM)) < 0.04
    assert f["holdout_gain"] > 0.3                                     # on the report rows the search never saw
    assert [x["kind"] for x in d["findings"]].count("payload_change") == 1


def test_any_sample_rate_100hz_payload(kuka, tmp_path):
    from diagnosis.cli import main

    log = prove.payload_log(REAL, tmp_path / "kuka_2_payload_100hz.mcap", decimate=2)
    assert main([str(kuka["model"]), str(log), "-o", str(tmp_path / "d"), "-q"]) == 0
    d = json.loads((tmp_path / "d" / "diagnosis.json").read_text())
    assert d["sample_rate_hz"] == 100.0 and d["filters_hz"]["velocity"] == pytest.approx(40.0)
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


@pytest.mark.parametrize("which", [1, pytest.param(3, marks=pytest.mark.xfail(reason=KUKA3_FALSE_NAME))])
def test_payload_spread_on_the_other_recordings(kuka, which):
    """The same 2 kg on kuka_1 (the model's own recording) and kuka_3: named on the hand within 20 % (real model
    error moves the estimate: docs/diagnosis.md)."""
    log = prove.payload_log(REAL, kuka["work"] / f"kuka_{which}_payload.mcap", which=which)
    d = prove.diagnose_cli(kuka["model"], log, kuka["work"] / f"diag_payload_{which}")
    pay = [f for f in d["findings"] if f["kind"] == "payload_change"]
    assert pay and pay[0]["joint"] == "lwr_6_joint", d["verdict"]
    assert pay[0]["effect"]["mass"] == pytest.approx(prove.PAYLOAD_MASS, rel=0.20)
