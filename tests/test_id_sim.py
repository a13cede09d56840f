"""Identification on simulator logs (true values known: configs/js2/sim_truth.yaml, read here by the tests only).

The session log comes from the real trial code (js2io trials on hil_sim.direct.DirectDriveGroup), generated once.
"""
from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
import yaml

from fixtures_id_sim import sim_session, synthetic_log, truth_vector
from identification.pipeline import IdentifyOptions, identify, predict_standard, rms_nrms



def cli(args, capsys):
    """Run js2-identify's main() in this process (same code path as the console script, no interpreter start-up)."""
    from identification.cli.identify import main

    capsys.readouterr()
    rc = main([str(a) for a in args])
    out, err = capsys.readouterr()
    return rc, out, err


@pytest.fixture(scope="module")
def session_log():
    return sim_session()


@pytest.fixture(scope="module")
def ident(session_log):
    return identify([session_log], IdentifyOptions(method="mixed"))


def test_mixed_method_recovers_drive_friction_within_5_percent(ident):
    tr, _ = truth_vector(ident.arm)
    np.testing.assert_allclose(ident.friction_static, tr.static, rtol=0.05)
    np.testing.assert_allclose(ident.friction_coulomb, tr.coulomb, rtol=0.05)
    np.testing.assert_allclose(ident.friction_viscous, tr.viscous, rtol=0.05)
    # the mixed method's model carries exactly these friction values (fixed in the RLS)
    for k in range(ident.arm.n):
        assert ident.model.beta[ident.param_index(f"B_{k + 1}")] == ident.friction_viscous[k]
        assert ident.model.beta[ident.param_index(f"fc_{k + 1}")] == ident.friction_coulomb[k]


def test_motor_inertias_within_10_percent_where_separately_identifiable(ident):
    tr, pi = truth_vector(ident.arm)
    ja, sd, alone = ident.motor_inertia()
    assert any(alone) and not all(alone), "the Js-2 regroups some J_a (vertical axis 1) and not others"
    for k in range(ident.arm.n):
        if alone[k]:
            assert ja[k] == pytest.approx(tr.motor_inertia[k], rel=0.10), k
        # regrouped or not: the base parameter holding J_a_k matches the truth's combination
        i = ident.bp.index_of(f"Ja_{k + 1}")
        assert ident.model.beta[i] == pytest.approx(ident.bp.beta(pi)[i], rel=0.10), ident.bp.names[i]


def test_validation_rms_within_1_2x_of_what_the_true_parameters_reach(ident):
    _, pi = truth_vector(ident.arm)
    pred, meas = predict_standard(ident, pi)
    rms_truth, _ = rms_nrms(pred, meas)
    ratio = ident.validation["rms"] / rms_truth
    assert np.all(ratio <= 1.2), ratio
    assert ident.validation["samples"] > 1000 and "validation" in ident.validation["data"][0]


def test_fig2_and_fig3_reproduced(ident):
    from identification.report import fig2, fig3

    vt = ident.velocity
    assert sorted(vt.axes_) == list(range(ident.arm.n))
    for m, ax in vt.axes_.items():
        pts = ax.points
        assert (pts[:, 0] > 0).sum() >= 3 and (pts[:, 0] < 0).sum() >= 3     # several speeds, both directions
        # the points lie on the eq. 5 line
        line = vt.predict(m, pts[:, 0])
        assert np.max(np.abs(pts[:, 1] - line)) < 0.05 * np.max(np.abs(pts[:, 1]))
        assert vt.score(m) > 0.99
    assert fig2(ident) is not None
    i_b4 = ident.param_index("B_4")
    mixed, simul = ident.methods["mixed"], ident.methods["simultaneous"]
    assert np.all(mixed.history[:, i_b4] == ident.friction_viscous[3])     # fixed under the mixed method
    assert np.ptp(simul.history[:, i_b4]) > 0                              # estimated under the simultaneous one
    i_j4 = ident.param_index("J_4z")
    assert "Ixx_link4" in ident.bp.names[i_j4]
    assert simul.history.shape[0] == mixed.history.shape[0] >= 100
    assert fig3(ident, ["J_4z", "B_4", "fc_4", "Ja_3"]) is not None


def test_cli_writes_model_urdf_report_verdict(session_log, tmp_path, capsys):
    out = tmp_path / "out"
    rc, _, err = cli([session_log, "-o", out, "-q"], capsys)
    assert rc == 0, err
    from js2spec.log import file_sha256
    from js2spec.model import load_model
    from js2spec.robot import check_urdf

    m = load_model(out)
    d = m.raw
    assert m.joints == ["j1", "j2", "j3", "j4", "j5", "j6"]
    assert set(d["friction"]) >= {"static", "coulomb", "viscous", "static_std", "coulomb_std", "viscous_std"}
    assert len(d["motor_inertia"]) == 6 and len(d["motor_inertia_std"]) == 6
    assert set(d["base_parameters"]) >= {"names", "values", "std"}
    assert set(d["validation"]) >= {"rms", "nrms"}
    assert d["method_key"] == "mixed" and d["inputs"][0]["sha256"] == file_sha256(session_log)
    assert all(np.isfinite(d["base_parameters"]["std"]))
    # the identified URDF is a physical arm a simulator accepts
    check_urdf(m.urdf_text, out / "robot_identified.urdf", m.joints)
    html = (out / "report.html").read_text()
    assert html.count("data:image/png;base64,") >= 3 and "Fig. 2" in html and "Fig. 3" in html
    v = json.loads((out / "verdict.json").read_text())
    assert v["pass"] is True and {c["check"] for c in v["checks"]} >= {"condition_number"}


def test_strict_exit_code_and_help(tmp_path, capsys):
    log = synthetic_log(tmp_path / "syn.mcap", seconds=6)
    out = tmp_path / "out"
    # the options cross-validation would choose are given: this test is about exit codes, not about choosing them
    fast = ["--no-offsets", "--no-sqrt-viscous", "--prior-weight", "1"]
    rc, _, err = cli([log, "-o", out, "-q", "--method", "simultaneous", "--no-report", *fast], capsys)
    assert rc == 0, err
    # --strict with an impossible threshold: non-zero exit, the verdict says why
    rc, _, err = cli([log, "-o", out, "-q", "--method", "simultaneous", "--no-report", "--strict", "--max-nrms", "1e-9",
                      *fast], capsys)
    assert rc == 1 and "verdict FAILED" in err
    v = json.loads((out / "verdict.json").read_text())
    assert v["pass"] is False and any(not c["pass"] and c["check"].startswith("validation_nrms") for c in v["checks"])
    r = subprocess.run([sys.executable, "-m", "identification.cli.identify", "--help"], capture_output=True, text=True)
    assert r.returncode == 0 and "mixed" in r.stdout and "model.yaml" in r.stdout and "Exit codes" in r.stdout


def test_truncated_log_is_identified_from_what_was_recovered(tmp_path, capsys):
    log = synthetic_log(tmp_path / "syn.mcap", seconds=12)
    cut = tmp_path / "cut.mcap"
    data = log.read_bytes()
    cut.write_bytes(data[: int(len(data) * 0.8)])
    out = tmp_path / "out"
    rc, _, err = cli([cut, "-o", out, "-q", "--no-report", "--method", "simultaneous", "--no-offsets",
                      "--no-sqrt-viscous", "--prior-weight", "1"], capsys)     # no cross-validation: not tested here
    assert rc == 0, err
    assert "truncated" in err and str(cut) in err
    d = yaml.safe_load((out / "model.yaml").read_text())
    assert d["inputs"][0]["truncated"] is True
    assert any("truncated" in n and "recovered" in n for n in d["notes"])


def test_bad_inputs_give_one_clear_message_and_exit_2(tmp_path, capsys):
    def _run_err(args):
        rc, _, err = cli(args, capsys)
        assert rc == 2, (rc, err)
        assert "Traceback" not in err
        lines = [ln for ln in err.strip().splitlines() if ln.strip()]
        assert len(lines) == 1, err
        return lines[0]

    out = tmp_path / "o"
    corrupt = tmp_path / "corrupt.mcap"
    corrupt.write_bytes(b"this is not an mcap file at all" * 10)
    assert str(corrupt) in _run_err([corrupt, "-o", out, "-q"])
    missing = tmp_path / "nope.mcap"
    assert str(missing) in _run_err([missing, "-o", out, "-q"])
    v2 = synthetic_log(tmp_path / "v2.mcap", version="2", seconds=3)
    msg = _run_err([v2, "-o", out, "-q"])
    assert str(v2) in msg and "version" in msg
    from js2spec.robot import load_robot

    urdf = load_robot("js2").urdf_text.replace('"j6"', '"wrist_roll"')
    bad_urdf = synthetic_log(tmp_path / "urdf.mcap", urdf_text=urdf, seconds=3)
    msg = _run_err([bad_urdf, "-o", out, "-q"])
    assert str(bad_urdf) in msg and "wrist_roll" in msg and "drives.yaml" in msg
    nan = synthetic_log(tmp_path / "nan.mcap", nan_joint=2, seconds=3)
    msg = _run_err([nan, "-o", out, "-q"])
    assert str(nan) in msg and "NaN" in msg and "j3" in msg
    no_vel = synthetic_log(tmp_path / "accel_only.mcap", seconds=3)
    msg = _run_err([no_vel, "-o", out, "-q", "--method", "mixed"])     # the default (auto) would pick simultaneous
    assert str(no_vel) in msg and "'velocity' trial" in msg
    msg = _run_err([no_vel, "-o", out, "-q", "--method", "simultaneous", "--fit-trials", "excitation"])
    assert "'excitation'" in msg and "acceleration" in msg


def test_synthetic_eq1_log_simultaneous_recovers_base_parameters_and_reports_gaps(tmp_path):
    """Torques that are exactly eq. 1 (plus white noise), with a few lost cycles: the simultaneous method recovers
    the base parameters within their reported standard errors, and the lost cycles are reported, not hidden."""
    log = synthetic_log(tmp_path / "syn.mcap", gap=(2000, 2004), nan_joint=1, nan_rows=3)
    r = identify([log], IdentifyOptions(method="simultaneous", physical=False))
    from identification.regressor import standard_vector

    pi = standard_vector(r.arm, motor_inertia=[3e-5, 3e-5, 1.6e-5, 8e-6, 6e-6, 6e-6],
                         viscous=[2e-4, 2.2e-4, 1.5e-4, 8e-5, 6e-5, 6e-5],
                         coulomb=[0.02, 0.024, 0.012, 0.008, 0.006, 0.006])
    z = (r.model.beta - r.bp.beta(pi)) / r.model.std
    assert np.all(np.abs(z) < 5), np.abs(z).max()
    assert np.mean(np.abs(z) < 2) > 0.8
    notes = " ".join(r.notes)
    assert "4 lost cycles" in notes and "NaN" in notes


def test_static_test_without_breakaway_events_detects_breakaway_from_the_data(session_log):
    """Eq. 2-4 from the encoder data alone (a log whose ramps carry no breakaway event) agrees with the events."""
    from identification.sequential import StaticFrictionTest
    from identification.trials import breakaways
    from js2spec.log import read_log

    log = read_log(session_log)
    from_events = breakaways(log, None)
    assert all(r.from_event for r in from_events)
    log.events = [e for e in log.events if e["kind"] != "breakaway"]
    detected = breakaways(log, None)
    assert len(detected) == len(from_events) and not any(r.from_event for r in detected)
    a = StaticFrictionTest(log.drives.n).fit(from_events).static_
    b = StaticFrictionTest(log.drives.n).fit(detected).static_
    np.testing.assert_allclose(b, a, rtol=0.03)


def test_session_split_over_one_log_per_trial(tmp_path, capsys):
    """The spec lets a session span several files (one per trial, t restarting at 0): identified together, with the
    validation trial in its own file, the mixed method meets the same friction targets."""
    logs = [sim_session((t,), seed=1) for t in ("static", "velocity", "acceleration")]
    val = sim_session(("validation",), seed=1)
    out = tmp_path / "out"
    rc, _, err = cli([*logs, "--validate", val, "-o", out, "-q", "--no-report"], capsys)
    assert rc == 0, err
    d = yaml.safe_load((out / "model.yaml").read_text())
    assert [i["trials"] for i in d["inputs"]] == [["static"], ["velocity"], ["acceleration"], ["validation"]]
    from hil_sim.truth import load_truth
    from js2spec.robot import load_robot

    tr = load_truth(load_robot("js2"))
    for key, true in (("static", tr.static), ("coulomb", tr.coulomb), ("viscous", tr.viscous)):
        np.testing.assert_allclose(d["friction"][key], true, rtol=0.05)
    assert "validation" in d["validation"]["data"][0]
