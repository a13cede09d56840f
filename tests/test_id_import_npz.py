"""js2-import on a damaged .npz: one line naming the file and what to do, exit 2, never a traceback (a truncated
archive raised zipfile.BadZipFile through the CLI until stop 43)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from identification.cli.import_recording import main

ROOT = Path(__file__).resolve().parents[1]
URDF = ROOT / "foreign_sim" / "tx40.urdf"
DRIVES = ROOT / "identification" / "examples" / "staubli_tx40" / "drives.yaml"


@pytest.mark.parametrize("damage", ["cut short", "cut to its head", "a member's bytes overwritten"])
def test_a_damaged_npz_is_one_line(tmp_path, capsys, damage):
    rng = np.random.default_rng(1)
    n = 4000
    good = tmp_path / "good.npz"
    np.savez(good, times=np.arange(n) / 500.0, positions=rng.normal(size=(n, 6)), torques=rng.normal(size=(n, 6)))
    raw = good.read_bytes()
    bad = tmp_path / "bad.npz"
    if damage == "cut short":
        bad.write_bytes(raw[:len(raw) - 2000])
    elif damage == "cut to its head":
        bad.write_bytes(raw[:5000])
    else:
        b = bytearray(raw)
        b[len(b) // 2:len(b) // 2 + 200] = b"\0" * 200
        bad.write_bytes(bytes(b))
    rc = main(["--npz", str(bad), "--urdf", str(URDF), "--drives", str(DRIVES), "-o", str(tmp_path / "o.mcap")])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1
    assert "bad.npz" in err[0] and "numpy.savez" in err[0] and "Traceback" not in err[0]
    assert not (tmp_path / "o.mcap").exists()
