"""Logs made from the real recordings in <repo>/../shared/data/real (resampled, or with wrong units) identify with the
plain command: filters follow the sample rate, the method and the held-out part follow the log, the textbook baseline
is reported beside the model, and a unit error fails the verdict with one line. Skipped when the data are absent."""
from __future__ import annotations

import numpy as np
import pytest
import yaml
from scipy.signal import decimate

from fixtures_id_sim import REAL, REPO
from identification.signals import choose_cutoffs

EX = REPO / "identification" / "examples"
pytestmark = pytest.mark.skipif(not (REAL / "staubli_tx40").is_dir() or not (REAL / "kuka_lwr4").is_dir(),
                                reason=f"real-arm recordings not found at {REAL} (CI has ../shared/data/real)")


def _log(tmp_path, arm: str, rate: float, torque_scale: float = 1.0):
    """The arm's recording decimated (anti-aliased torque, plain positions) to ``rate`` and imported with no trials."""
    from identification import importer as im

    if arm == "kuka":
        rec = im.load_npz(REAL / "kuka_lwr4" / "data" / "measurements_1.npz")
        urdf, drives, side, fs0 = REAL / "kuka_lwr4" / "kinematics" / "kuka_lwr4.urdf", EX / "kuka_lwr4" / "drives.yaml", \
            "joint", 200.0
    else:
        d = REAL / "staubli_tx40"
        rec = im.load_csvs(d / "data" / "pos_read_data.csv", d / "data" / "curr_data.csv", rate=5000.0)
        urdf, drives, side, fs0 = d / "kinematics" / "tx40_mdh_modified.urdf", EX / "staubli_tx40" / "drives.yaml", \
            "motor", 5000.0
    q = int(round(fs0 / rate))
    tau = decimate(rec.torque, q, ftype="fir", zero_phase=True, axis=0) if q > 1 else rec.torque
    r = im.Recording(rec.t[::q], rec.position[::q], torque_scale * tau, source=f"{arm} at {rate:g} Hz")
    # js2-import refuses a unit-looking factor itself (tests/test_id_import_validation.py); a scaled log is written
    # here with that check off, as --no-unit-check would, so that the verdict's own check is what is tested
    return im.write_log(r, urdf, drives, tmp_path / f"{arm}_{rate:g}.mcap", rate=rate, positions_side=side,
                        unit_check=torque_scale == 1.0)


def _identify(tmp_path, log, *extra):
    from identification.cli.identify import main

    out = tmp_path / "out"
    rc = main([str(log), "-o", str(out), "--no-report", "-q", *extra])
    return rc, out


@pytest.mark.parametrize("arm,rate", [("kuka", 100.0), ("tx40", 500.0), ("tx40", 1000.0)])
def test_resampled_real_logs_identify_without_flags(tmp_path, capsys, arm, rate):
    log = _log(tmp_path, arm, rate)
    rc, out = _identify(tmp_path, log)
    assert rc == 0, capsys.readouterr().err
    m = yaml.safe_load((out / "model.yaml").read_text())
    f = m["filters"]
    assert 0 < f["acceleration_cutoff_hz"] <= f["velocity_cutoff_hz"] < rate / 2
    if rate >= 125:     # the paper's cut-offs where the rate allows them
        assert (f["velocity_cutoff_hz"], f["acceleration_cutoff_hz"]) == (50.0, 7.0) and "paper" in f["reason"]
    else:
        assert f["velocity_cutoff_hz"] == pytest.approx(0.4 * rate) and "Nyquist" in f["reason"]
    # the method and the held-out part follow the log, each said in one note
    assert m["method_key"] == "simultaneous"
    assert sum(n.startswith("method: simultaneous") for n in m["notes"]) == 1
    assert sum("held out for validation" in n for n in m["notes"]) == 1
    # the textbook baseline beside the exported model, on the same samples
    b = m["validation"]["baseline"]
    assert len(b["rms"]) == len(m["joints"]) and b["relative_error_overall"] > 0
    assert b["ratio_js2_to_baseline"] == pytest.approx(m["validation"]["relative_error_overall"]
                                                       / b["relative_error_overall"])
    # exported: nothing negative, every link physical
    assert min(m["motor_inertia"]) >= 0 and min(m["friction"]["viscous"]) >= 0 and min(m["friction"]["coulomb"]) >= 0
    assert all(lk["mass"] > 0 and lk["physically_consistent"] for lk in m["links"].values())


def test_cutoffs_follow_the_sample_rate_and_the_motion():
    assert (choose_cutoffs(4000.0, 1.0).fc_velocity_hz, choose_cutoffs(4000.0, 1.0).fc_acceleration_hz) == (50.0, 7.0)
    low = choose_cutoffs(50.0, 0.5)
    assert low.fc_velocity_hz == 20.0 and low.fc_acceleration_hz == 7.0 and "Nyquist" in low.reason
    fast = choose_cutoffs(1000.0, 6.0)              # a 6 Hz motion is not filtered at 7 Hz
    assert fast.fc_acceleration_hz == 12.0 and "motion bandwidth" in fast.reason
    assert choose_cutoffs(20.0, 6.0).fc_acceleration_hz <= 8.0     # capped below Nyquist
    with pytest.raises(ValueError, match="Nyquist"):
        choose_cutoffs(100.0, fc_velocity_hz=50.0)


def test_cutoff_above_nyquist_is_one_line_exit_2(tmp_path, capsys):
    log = _log(tmp_path, "kuka", 100.0)
    rc, _ = _identify(tmp_path, log, "--fc-velocity", "50")
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1 and str(log) in err and "Nyquist" in err


def test_torques_in_mNm_fail_the_verdict_with_the_units_sentence(tmp_path, capsys):
    log = _log(tmp_path, "kuka", 100.0, torque_scale=1000.0)
    rc, out = _identify(tmp_path, log, "--strict", "--prior-weight", "1")
    assert rc == 1
    v = yaml.safe_load((out / "verdict.json").read_text())
    assert not v["pass"] and "torques look 1000x too large: check the units" in v["reasons"]
    assert any("total link mass" in r for r in v["reasons"])
