"""scripts/rattle_features.py: the features stop 38 read on the bench's base-axis rattles to tell a free link's play
from its spring (docs/diagnosis.md, stop 38). At 250 Hz a play's share of the link's torque missed rises with the
load the link carries (pushed on a contact when the load is high) and a spring's does not; recorded here as the
bench records its cases 15 (a 0.026 rad play) and 97 (a 2120 N*m/rad spring), both on the vertical base axis."""
import json
import sys
from pathlib import Path

import pytest

from fixtures_diag import bench_recording, clean_model

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))
import rattle_features  # noqa: E402


def test_a_base_play_and_a_base_spring_at_250_hz_differ_in_the_share_by_load(tmp_path, capsys):
    play, rec_play = bench_recording(15, tmp_path)
    spring, rec_spring = bench_recording(97, tmp_path)
    assert [(e["kind"], e["joints"]) for e in play["effects"]] == [("backlash", [0])]
    assert [(e["kind"], e["joints"]) for e in spring["effects"]] == [("joint_elasticity", [0])]
    assert play["cycle_hz"] == spring["cycle_hz"] == 250.0
    assert rattle_features.main([str(clean_model()), "0", str(rec_play), str(rec_spring)]) == 0
    f_play, f_spring = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    for f in (f_play, f_spring):      # both in the loop's limit cycle: the gear swings 10-14 mrad at 22-28 Hz
        assert 8 < f["swing_mrad"] < 16 and 20 < f["swing_hz"] < 30
        assert f["r2_fir"] >= f["r2"] > 0.85
        assert len(f["alpha_by_load"]) == 3 and len(f["alpha_by_swing"]) == 2
    # a free link in a gap misses its whole inertial torque (alpha 1); one on a spring above its resonance more
    assert f_play["alpha"] == pytest.approx(1.0, abs=0.05) and f_spring["alpha"] > 1.08
    # the share by load: a play's rises with the load (the contact), a spring's does not
    assert f_play["load_ratio"] > 1.1 > 1.05 > f_spring["load_ratio"]


def test_a_recording_or_joint_it_cannot_read_is_one_line(tmp_path, capsys):
    assert rattle_features.main([str(tmp_path / "nomodel"), "0", str(tmp_path / "x.mcap")]) == 2
    assert "Traceback" not in capsys.readouterr().err
    bad = tmp_path / "bad.mcap"
    bad.write_text("not mcap")
    assert rattle_features.main([str(clean_model()), "0", str(bad)]) == 2
    err = capsys.readouterr().err
    assert "bad.mcap" in err and "Traceback" not in err
