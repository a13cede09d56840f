"""js2-diagnose as a newcomer meets it: help, bad input (one line, exit 2), outputs on a real run."""
import json

import pytest

from diagnosis.cli import main
from fixtures_diag import clean_model, recording


def test_help_explains_the_tool(capsys):
    with pytest.raises(SystemExit) as ex:
        main(["--help"])
    assert ex.value.code == 0
    out = capsys.readouterr().out
    assert "held-out" in out and "stribeck" in out and "effects.yaml" in out


def test_bad_recording_is_one_clear_line(tmp_path, capsys):
    bad = tmp_path / "bad.mcap"
    bad.write_text("not mcap")
    assert main([str(clean_model()), str(bad), "-o", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "bad.mcap" in err[0] and "not an MCAP file" in err[0]


def test_missing_model_is_one_clear_line(tmp_path, capsys):
    assert main([str(tmp_path / "nomodel"), str(recording("[]")), "-o", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "model file not found" in err and "Traceback" not in err


def test_strict_exit_code_and_outputs(tmp_path, capsys):
    rec = recording(json.dumps([{"kind": "load_dependent_friction", "joints": [1], "coefficient": 0.15}]))
    out = tmp_path / "diag"
    assert main([str(clean_model()), str(rec), "-o", str(out), "--strict", "-q"]) == 1
    d = json.loads((out / "diagnosis.json").read_text())
    assert d["findings"][0]["kind"] == "load_dependent_friction"
    assert (out / "report.html").read_text().count("data:image/png;base64") >= 2
    assert "load_dependent_friction" in capsys.readouterr().out
