"""The two real arms in <repo>/../shared/data/real: imported with js2-import, identified, validated on held-out data
and compared with what their authors published. Skipped (with the reason) when the data folder is absent."""
from __future__ import annotations

import numpy as np
import pytest

from fixtures_id_sim import REAL

pytestmark = pytest.mark.skipif(not (REAL / "staubli_tx40").is_dir() or not (REAL / "kuka_lwr4").is_dir(),
                                reason=f"real-arm recordings not found at {REAL} (CI has ../shared/data/real)")


@pytest.fixture(scope="module")
def tx40(tmp_path_factory):
    from identification.examples.real_arms import run_tx40

    return run_tx40(REAL, tmp_path_factory.mktemp("tx40"))


@pytest.fixture(scope="module")
def kuka(tmp_path_factory):
    from identification.examples.real_arms import run_kuka

    return run_kuka(REAL, tmp_path_factory.mktemp("kuka"))


def test_tx40_import_is_a_conforming_log_with_the_coupled_wrist(tx40):
    ident = tx40["ident"]
    log = ident.logs[0]
    assert log.source.startswith("import:") and log.cycle_hz == 5000.0
    assert log.trials() == ["excitation", "validation"]
    K = log.drives.gear_ratio_matrix
    assert K[5, 4] != 0                                              # q6 depends on motor 5: coupled wrist
    # the importer wrote the recording unchanged (motor angles, effort as motor torque)
    raw = np.loadtxt(REAL / "staubli_tx40" / "data" / "pos_read_data.csv", delimiter=",", skiprows=1, max_rows=50)
    np.testing.assert_allclose(log.feedback.motor_position[:50], raw)


def test_tx40_friction_agrees_with_figaroh_published_values(tx40):
    ours, pub = tx40["ours"], tx40["figaroh_bp"]
    for k in range(4):      # uncoupled axes: same model structure, values must agree
        assert ours["fv"][k] == pytest.approx(pub["fv"][k], rel=0.10), ("fv", k + 1)
        assert ours["fs"][k] == pytest.approx(pub["fs"][k], rel=0.10), ("fs", k + 1)
    assert ours["fv"][5] == pytest.approx(pub["fv"][5], rel=0.10)      # motor 6 <-> FIGAROH's coupling term fvm6
    for k in (2, 3):
        assert ours["Ia"][k] == pytest.approx(pub["Ia"][k], rel=0.15), ("Ia", k + 1)


def test_tx40_validation_rms_is_on_par_with_the_published_model(tx40):
    rms, pub = np.asarray(tx40["rms"]), np.asarray(tx40["rms_published"])
    assert np.all(rms <= 1.25 * pub), (rms, pub)
    assert np.all(tx40["nrms"] < 0.12)
    assert tx40["ident"].physical.physical_.all()


def test_kuka_identified_and_validated_on_another_trajectory(kuka):
    ident = kuka["ident"]
    assert ident.arm.torque_side == "joint" and ident.arm.n == 7
    assert "kuka_3" in ident.validation["data"][0]
    phys = np.asarray(kuka["rms_physical"])
    cad = np.asarray(kuka["refs"]["CAD URDF"])
    # the physically consistent identified model predicts the held-out trajectory at least as well as the CAD
    # inertials with refitted drive terms on most joints, and never far worse
    assert np.sum(phys <= cad) >= 4 and phys.mean() < cad.mean() and np.all(phys < 1.5 * cad), (phys, cad)
    assert np.all(phys < 1.0)
    assert ident.physical.physical_.all()


def test_logs_of_different_arms_are_refused_with_one_message(tx40, kuka, tmp_path, capsys):
    from identification.cli.identify import main

    a, b = tx40["ident"].logs[0].path, kuka["ident"].logs[0].path
    rc = main([str(a), "--validate", str(b), "-o", str(tmp_path / "o"), "-q", "--method", "simultaneous",
               "--fit-trials", "excitation"])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1 and str(b) in err and "different arm" in err
