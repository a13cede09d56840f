"""scripts/diagnose_rankings.py: every candidate of every ladder step, dumped per recording (stop 37 read its rule
changes on these dumps)."""
import json
import sys
from pathlib import Path

from fixtures_diag import clean_model, recording

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))
import diagnose_rankings  # noqa: E402


def test_the_dump_holds_every_steps_candidates_and_the_finding(tmp_path, capsys):
    rec = recording(json.dumps([{"kind": "load_dependent_friction", "joints": [1], "coefficient": 0.15}]))
    assert diagnose_rankings.main([str(clean_model()), str(tmp_path), str(rec)]) == 0
    d = json.loads((tmp_path / f"{Path(rec).stem}.json").read_text())
    assert [(a["kind"], a["joint"]) for a in d["accepted"]][0] == ("load_dependent_friction", 1)
    assert d["verdict"].startswith("the model leaves out: load_dependent_friction")
    first = d["rankings"][0]
    assert len(d["rankings"]) >= 2 and len(first) > 20
    row = next(r for r in first if r["term"] == "LoadDependentFriction" and r["joint"] == 1)
    assert row["ok"] and abs(row["coef"][0] - 0.15) < 0.03 and len(row["std"]) == 1
    assert {"own", "sel", "all", "cap", "fit", "hold", "why", "rej", "effect", "hyper"} <= set(row)
    # a dump that exists is kept, not made again
    stamp = (tmp_path / f"{Path(rec).stem}.json").stat().st_mtime_ns
    assert diagnose_rankings.main([str(clean_model()), str(tmp_path), str(rec)]) == 0
    assert (tmp_path / f"{Path(rec).stem}.json").stat().st_mtime_ns == stamp


def test_a_missing_model_or_recording_is_one_line(tmp_path, capsys):
    assert diagnose_rankings.main([str(tmp_path / "nomodel"), str(tmp_path), str(recording("[]"))]) == 2
    assert "model.yaml: not found" in capsys.readouterr().err
    assert diagnose_rankings.main([str(clean_model()), str(tmp_path), str(tmp_path / "none.mcap")]) == 2
    err = capsys.readouterr().err
    assert "not found" in err and "none.mcap" in err and "Traceback" not in err
    bad = tmp_path / "bad.mcap"                  # a file js2 cannot read: one line, the good one still dumped
    bad.write_text("not mcap")
    good = recording("[]")
    assert diagnose_rankings.main([str(clean_model()), str(tmp_path / "out"), str(bad), str(good)]) == 2
    err = capsys.readouterr().err
    assert "bad.mcap" in err and "not an MCAP file" in err and "Traceback" not in err
    assert not (tmp_path / "out" / "bad.json").exists() and (tmp_path / "out" / f"{Path(good).stem}.json").is_file()
