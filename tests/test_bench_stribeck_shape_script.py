"""scripts/bench_stribeck_shape.py: a bench case with one concealed Stribeck hump, recorded and diagnosed; the script
prints the ladder's reading (shape 2, 13 points) and the refined one (docs/diagnosis.md, stop 39)."""
import json
import sys
from pathlib import Path

import pytest

from fixtures_diag import clean_model

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))
import bench_stribeck_shape  # noqa: E402


def test_one_case_is_recorded_diagnosed_and_its_hump_read_with_its_shape(tmp_path, capsys):
    # case 3: a 500 Hz recording, a shape-1 hump (v_s 3.07 rad/s) on motor 5; the committed row reads shape 1 at 3.28
    out = tmp_path / "out"
    assert bench_stribeck_shape.main(["--first", "3", "--cases", "1", "--out", str(out), "--model", str(clean_model()),
                                      "--json", str(tmp_path / "rows.json")]) == 0
    data = json.loads((tmp_path / "rows.json").read_text())
    (row,) = data["rows"]
    committed = json.loads((Path(__file__).resolve().parents[1] / "docs" / "bench" /
                            "stribeck-shape-2026-11-28-stop39-dev.json").read_text())["rows"][3]
    assert (row["seed"], row["cycle_hz"], row["joint"], row["truth"]) == (
        3, 500.0, 4, committed["truth"])                  # the same draw as the committed rows
    assert row["truth"]["shape"] == 1.0 and row["read"]["shape"] == 1.0 and row["read"]["resolved"]
    assert row["read"]["velocity"] == pytest.approx(row["truth"]["velocity"], rel=0.15)
    assert row["read"]["ladder_shape"] == 2.0 and row["read"]["ladder_velocity"] > 1.3 * row["truth"]["velocity"]
    assert data["summary"]["named"] == data["summary"]["shape_right"] == 1
    printed = capsys.readouterr().out
    assert "case   3:" in printed and "shape right: 1 of 1" in printed


def test_no_cases_or_no_model_is_one_error_line(tmp_path, capsys):
    assert bench_stribeck_shape.main(["--cases", "0"]) == 2
    assert "must be at least 1" in capsys.readouterr().err
    assert bench_stribeck_shape.main(["--model", str(tmp_path / "nomodel"), "--out", str(tmp_path / "out")]) == 2
    assert "holds no model.yaml" in capsys.readouterr().err and not (tmp_path / "nomodel").exists()
