"""js2-import: plain CSV / NumPy recordings + URDF + drives.yaml -> a js2 log the reader accepts, without silent
resampling (missing samples stay missing), with clear errors."""
from __future__ import annotations

import numpy as np
import pytest

from identification.cli.import_recording import main
from js2spec.log import read_log
from js2spec.robot import load_robot


def _write_csv(path, header, rows):
    np.savetxt(path, rows, delimiter=",", header=",".join(header), comments="")


def test_csv_with_time_column_and_a_gap_round_trips(tmp_path, capsys):
    robot = load_robot("js2")
    n = robot.drives.n
    t = np.arange(1000) / 500.0
    keep = np.ones(len(t), dtype=bool)
    keep[400:410] = False                      # 10 samples missing from the recording
    q = np.sin(np.outer(t, np.arange(1, n + 1)))
    tau = 0.01 * np.cos(np.outer(t, np.arange(1, n + 1)))
    _write_csv(tmp_path / "pos.csv", ["time"] + robot.drives.joints, np.column_stack([t, q])[keep])
    _write_csv(tmp_path / "tau.csv", robot.drives.joints, tau[keep])
    drives = tmp_path / "drives.yaml"
    drives.write_text(robot.drives_yaml)
    out = tmp_path / "rec.mcap"
    rc = main(["--positions", str(tmp_path / "pos.csv"), "--time-column", "time", "--torques",
               str(tmp_path / "tau.csv"), "--urdf", str(robot.urdf_path), "--drives", str(drives),
               "--trial", "excitation:0:1.2", "--trial", "validation:1.3:2", "-o", str(out)])
    assert rc == 0, capsys.readouterr().err
    log = read_log(out)
    assert log.source.startswith("import:") and log.cycle_hz == 500.0
    assert log.lost_cycles == 10                              # not interpolated
    np.testing.assert_allclose(log.feedback.motor_position, q[keep], rtol=1e-12)
    np.testing.assert_allclose(log.feedback.torque, tau[keep], rtol=1e-12)
    kt = np.asarray(robot.drives.torque_constant)
    np.testing.assert_allclose(log.feedback.motor_current, tau[keep] / kt, rtol=1e-12)   # motor side needs current
    assert log.trials() == ["excitation", "validation"]


def test_import_errors_name_the_file(tmp_path, capsys):
    robot = load_robot("js2")
    drives = tmp_path / "drives.yaml"
    drives.write_text(robot.drives_yaml)
    _write_csv(tmp_path / "pos5.csv", ["a", "b", "c", "d", "e"], np.zeros((10, 5)))
    _write_csv(tmp_path / "tau.csv", robot.drives.joints, np.zeros((10, 6)))
    rc = main(["--positions", str(tmp_path / "pos5.csv"), "--torques", str(tmp_path / "tau.csv"), "--rate", "100",
               "--urdf", str(robot.urdf_path), "--drives", str(drives), "-o", str(tmp_path / "x.mcap")])
    err = capsys.readouterr().err
    assert rc == 2 and "pos5.csv" in err and "5 position columns" in err and "Traceback" not in err
    bad_urdf = tmp_path / "bad.urdf"
    bad_urdf.write_text(robot.urdf_text.replace('name="j2"', 'name="shoulder"'))
    _write_csv(tmp_path / "pos.csv", robot.drives.joints, np.zeros((10, 6)))
    rc = main(["--positions", str(tmp_path / "pos.csv"), "--torques", str(tmp_path / "tau.csv"), "--rate", "100",
               "--urdf", str(bad_urdf), "--drives", str(drives), "-o", str(tmp_path / "x.mcap")])
    err = capsys.readouterr().err
    assert rc == 2 and "bad.urdf" in err and "shoulder" in err


def test_an_import_replaces_its_output_whole_and_never_writes_through_a_link(tmp_path, monkeypatch, capsys):
    """The log is written beside -o and renamed over it when complete: -o as a symlink is replaced (its target,
    another run's file, is untouched), and an import that fails while writing leaves the old file as it was and no
    partial file behind (two bench runs sharing a recording once read one mid-write: docs/diagnosis.md, stop 31)."""
    import identification.importer as im

    robot = load_robot("js2")
    n = robot.drives.n
    t = np.arange(200) / 100.0
    _write_csv(tmp_path / "pos.csv", robot.drives.joints, np.sin(np.outer(t, np.arange(1, n + 1))))
    _write_csv(tmp_path / "tau.csv", robot.drives.joints, 0.01 * np.ones((len(t), n)))
    drives = tmp_path / "drives.yaml"
    drives.write_text(robot.drives_yaml)
    args = ["--positions", str(tmp_path / "pos.csv"), "--torques", str(tmp_path / "tau.csv"), "--rate", "100",
            "--urdf", str(robot.urdf_path), "--drives", str(drives), "-o"]
    target = tmp_path / "other_run.mcap"
    target.write_bytes(b"another run's recording")
    link = tmp_path / "rec.mcap"
    link.symlink_to(target)
    assert main(args + [str(link)]) == 0, capsys.readouterr().err
    assert not link.is_symlink() and len(read_log(link).feedback.motor_position) == len(t)
    assert target.read_bytes() == b"another run's recording"
    before = link.read_bytes()

    class DiskFull(im.LogWriter):          # the file is open and its header written when the samples fail
        def feedback(self, *a, **k):
            raise OSError("No space left on device")
    monkeypatch.setattr(im, "LogWriter", DiskFull)
    with pytest.raises(OSError, match="No space left"):
        im.write_log(im.Recording(t, np.zeros((len(t), n)), np.zeros((len(t), n)), None, "x"), robot.urdf_path,
                     drives, link, rate=100.0)
    assert link.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir() if p.name.startswith(".")) == []
