"""js2-import's validation on a real recording (KUKA LWR4+, joint torque sensors): cells that are not numbers named
by line and column, an explicit NaN policy, time stamps in the wrong unit, torques in the wrong unit (checked
against the nominal URDF) -> one line, exit 2, with the hint; the clean recording imports."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from identification.cli.import_recording import main
from js2spec.log import read_log

REPO = Path(__file__).resolve().parents[1]
KUKA = REPO.parent / "shared" / "data" / "real" / "kuka_lwr4"
DRIVES = REPO / "identification" / "examples" / "kuka_lwr4" / "drives.yaml"
URDF = KUKA / "kinematics" / "kuka_lwr4.urdf"
pytestmark = pytest.mark.skipif(not KUKA.is_dir(), reason="shared/data/real not present")


@pytest.fixture(scope="module")
def kuka_csv(tmp_path_factory):
    """The first 20 s of measurements_1 as CSVs (time column in seconds)."""
    d = np.load(KUKA / "data" / "measurements_1.npz")
    k = d["times"] <= d["times"][0] + 20.0
    root = tmp_path_factory.mktemp("kuka")
    joints = [f"j{i}" for i in range(d["positions"].shape[1])]
    t = d["times"][k] - d["times"][k][0]
    np.savetxt(root / "pos.csv", np.column_stack([t, d["positions"][k]]), delimiter=",",
               header=",".join(["time"] + joints), comments="", fmt="%.9g")
    np.savetxt(root / "tau.csv", d["torques"][k], delimiter=",", header=",".join(joints), comments="", fmt="%.9g")
    return root, t, d["torques"][k]


def _run(root, *extra, pos="pos.csv", tau="tau.csv"):
    return main(["--positions", str(root / pos), "--time-column", "time", "--torques", str(root / tau),
                 "--positions-side", "joint", "--urdf", str(URDF), "--drives", str(DRIVES),
                 "-o", str(root / "out.mcap"), *extra])


def _err(capsys):
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("js2-import: error:") and "Traceback" not in err, err
    return err


def test_clean_recording_imports(kuka_csv, capsys):
    root, t, tau = kuka_csv
    assert _run(root) == 0, capsys.readouterr().err
    log = read_log(root / "out.mcap")
    n = len(log.feedback)
    assert 0.99 * len(tau) <= n <= len(tau)        # duplicated cycles of the jittery clock dropped, no more
    np.testing.assert_allclose(log.feedback.torque[:100], tau[:100], rtol=1e-6, atol=1e-9)
    (root / "out.mcap").unlink()


def test_text_cell_named_by_line_and_column(kuka_csv, capsys):
    root, _, _ = kuka_csv
    lines = (root / "tau.csv").read_text().splitlines()
    cells = lines[101].split(",")
    cells[3] = "12,5"[:2] + "abc"
    lines[101] = ",".join(cells)
    (root / "tau_text.csv").write_text("\n".join(lines) + "\n")
    assert _run(root, tau="tau_text.csv") == 2
    err = _err(capsys)
    assert "tau_text.csv" in err and "line 102, column 'j3': '12abc'" in err and "not numbers" in err


def test_nan_policy_is_explicit(kuka_csv, capsys):
    root, _, tau = kuka_csv
    lines = (root / "tau.csv").read_text().splitlines()
    for ln in (50, 51, 52):
        cells = lines[ln].split(",")
        cells[1] = ""
        lines[ln] = ",".join(cells)
    (root / "tau_gap.csv").write_text("\n".join(lines) + "\n")
    assert _run(root, "--nan", "refuse", tau="tau_gap.csv") == 2
    assert "3 samples have missing/NaN values (first at sample 49" in _err(capsys)
    assert _run(root, tau="tau_gap.csv") == 0
    out = capsys.readouterr().out
    assert "3 samples with missing/NaN values marked invalid" in out
    log = read_log(root / "out.mcap")
    assert (~log.feedback.valid).sum() == 3 and not log.feedback.valid[49:52, 1].any()   # before any dropped row
    (root / "out.mcap").unlink()


def test_time_in_ms_gets_a_hint(kuka_csv, capsys):
    root, t, _ = kuka_csv
    lines = (root / "pos.csv").read_text().splitlines()
    out = [lines[0]]
    for ln in lines[1:]:
        c = ln.split(",")
        c[0] = repr(float(c[0]) * 1000.0)
        out.append(",".join(c))
    (root / "pos_ms.csv").write_text("\n".join(out) + "\n")
    assert _run(root, pos="pos_ms.csv") == 2
    err = _err(capsys)
    rate = 1.0 / np.median(np.diff(t))
    assert "is not a servo rate" in err and f"ms: {rate:.0f} Hz" in err and "--time-unit" in err
    assert _run(root, "--time-unit", "ms", pos="pos_ms.csv") == 0
    assert read_log(root / "out.mcap").cycle_hz == pytest.approx(rate, rel=1e-3)
    (root / "out.mcap").unlink()


@pytest.mark.parametrize("factor,what", [(1000.0, "1000x too large"), (1e-3, "1000x too small"),
                                         (180 / np.pi, "(180/pi) too large")])
def test_torques_in_the_wrong_unit_are_refused(kuka_csv, capsys, factor, what):
    root, _, tau = kuka_csv
    joints = [f"j{i}" for i in range(tau.shape[1])]
    np.savetxt(root / "tau_x.csv", tau * factor, delimiter=",", header=",".join(joints), comments="", fmt="%.9g")
    assert _run(root, tau="tau_x.csv") == 2
    err = _err(capsys)
    assert what in err and "nominal URDF" in err and "--no-unit-check" in err
    assert _run(root, "--no-unit-check", tau="tau_x.csv") == 0      # the documented override
    capsys.readouterr()
    (root / "out.mcap").unlink()


@pytest.mark.parametrize("kind", ["random bytes", "non-UTF-8", "directory", "empty"])
def test_bad_files_one_line(kuka_csv, tmp_path, capsys, kind):
    root, _, _ = kuka_csv
    bad = tmp_path / "bad.csv"
    if kind == "random bytes":
        bad.write_bytes(np.random.default_rng(1).integers(0, 256, 3000, dtype=np.uint8).tobytes())
    elif kind == "non-UTF-8":
        bad.write_bytes("t,j0\n1,\xe4\n".encode("latin-1"))
    elif kind == "directory":
        bad.mkdir()
    else:
        bad.write_bytes(b"")
    rc = main(["--positions", str(bad), "--time-column", "time", "--torques", str(root / "tau.csv"),
               "--positions-side", "joint", "--urdf", str(URDF), "--drives", str(DRIVES), "-o", str(tmp_path / "o.mcap")])
    assert rc == 2
    assert "bad.csv" in _err(capsys)
    # a binary file given as the URDF or the drives file is named too
    for opt in ("--urdf", "--drives"):
        args = ["--positions", str(root / "pos.csv"), "--time-column", "time", "--torques", str(root / "tau.csv"),
                "--positions-side", "joint", "--urdf", str(URDF), "--drives", str(DRIVES), "-o", str(tmp_path / "o.mcap")]
        args[args.index(opt) + 1] = str(bad)
        assert main(args) == 2
        assert "bad.csv" in _err(capsys)
