"""js2-diagnose --replay and js2-sim --replay on a real recording (KUKA LWR4+, ../shared/data/real/kuka_lwr4: 200 Hz,
joint torque sensors, K = I): the payload protocol of scripts/prove_diagnosis_real.py (2 kg added to kuka_2's torques
by RNEA), replayed through the simulator with the identified model, then with the payload the diagnosis found.
Skipped when the data folder is absent. The figures are those of docs/diagnosis.md ("Replay")."""
from __future__ import annotations

import json

import numpy as np
import pytest

from fixtures_id_sim import REAL, prove_diagnosis_real

pytestmark = pytest.mark.skipif(not (REAL / "kuka_lwr4").is_dir(),
                                reason=f"real-arm recordings not found at {REAL} (CI has ../shared/data/real)")

prove = prove_diagnosis_real()


@pytest.fixture(scope="module")
def kuka_payload(tmp_path_factory, kuka_diag):
    from diagnosis.cli import main

    work = tmp_path_factory.mktemp("kuka_replay")
    model = kuka_diag["model"]                        # the plain js2-identify kuka_1.mcap (conftest, shared)
    log = prove.payload_log(REAL, work / "kuka_2_payload.mcap")
    assert main([str(model), str(log), "-o", str(work / "diag"), "--replay", "-q"]) == 0
    return work, model, log, json.loads((work / "diag" / "diagnosis.json").read_text())


def test_real_recording_replay_gap_shrinks_with_the_found_payload(kuka_payload):
    _, _, _, d = kuka_payload
    rep = d["replay"]
    assert [e["kind"] for e in rep["effects"]] == [f["kind"] for f in d["findings"]]
    before, after = np.array(rep["rms_model"]), np.array(rep["rms_model_effects"])
    # docs/diagnosis.md: shoulder (lwr_1) 9.0 -> 0.33 N m, lwr_3 5.6 -> 0.20 N m, gain 79 % (+-10 points)
    assert before[1] == pytest.approx(9.0, rel=0.1) and after[1] == pytest.approx(0.33, rel=0.25)
    assert before[3] == pytest.approx(5.6, rel=0.1) and after[3] == pytest.approx(0.20, rel=0.25)
    assert rep["gain"] == pytest.approx(0.79, abs=0.10)
    assert np.all(after <= before * 1.01)               # no joint gets worse
    assert before[6] == pytest.approx(0.30, rel=0.1) and after[6] == pytest.approx(0.27, rel=0.25)   # the least
    assert rep["agreement_with_diagnosis_prediction"] < 1e-9
    fw = rep["forward"]
    p0, p1 = np.array(fw["model"]["position_rms"]), np.array(fw["model_effects"]["position_rms"])
    # forward replay (recorded torque + 5 Hz tracking) follows the whole report part, closer with the payload on
    # every joint; docs/diagnosis.md: lwr_3 7.7 -> 0.51 mrad, lwr_5 30 -> 2.7 mrad
    assert fw["model"]["followed"] == 1.0 and fw["model_effects"]["followed"] == 1.0
    assert np.all(p1 < p0)
    assert p0[3] == pytest.approx(0.0077, rel=0.15) and p1[3] == pytest.approx(0.00051, rel=0.3)
    assert p0[5] == pytest.approx(0.030, rel=0.15) and p1[5] == pytest.approx(0.0027, rel=0.3)


def test_js2_sim_replays_a_real_recording(kuka_payload, capsys):
    from hil_sim.cli import main
    from js2spec.log import read_log

    work, model, log, _ = kuka_payload
    out = work / "sim.mcap"
    assert main(["--replay", str(log), "--model", str(model), "--effects", str(work / "diag" / "effects.yaml"),
                 "-o", str(out)]) == 0
    text = capsys.readouterr().out
    assert "lwr_1_joint" in text and "model + effects" in text
    sim = read_log(out)
    assert sim.drives.torque_side == "joint" and len(sim.feedback) >= 0.95 * len(read_log(log).feedback)
