"""The driver layer as plug-ins: js2io knows no simulator (rigs chosen by name through entry points), and the PDO
layout comes from one data source, the drives' EDS, for both the master and the simulated drives."""
from __future__ import annotations

import ast
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from js2spec.errors import ConfigError
from js2spec.log import read_log
from js2spec.robot import load_robot

from test_acq_support import short_trials_yaml

ROOT = Path(__file__).resolve().parents[1]
ROBOT = load_robot("js2")


def test_js2io_imports_nothing_from_hil_sim():
    """Read every js2io module's imports (AST), then import them all in a fresh interpreter: no hil_sim anywhere."""
    mods = sorted(p for p in (ROOT / "js2io").glob("*.py"))
    assert len(mods) >= 10
    for p in mods:
        for node in ast.walk(ast.parse(p.read_text())):
            names = ([a.name for a in node.names] if isinstance(node, ast.Import)
                     else [node.module or ""] if isinstance(node, ast.ImportFrom) else [])
            assert not any(n.split(".")[0] == "hil_sim" for n in names), f"{p.name} imports {names}"
    code = ("import sys, importlib\n"
            f"for m in {[p.stem for p in mods]!r}:\n"
            "    importlib.import_module('js2io.' + m)\n"
            "bad = sorted(m for m in sys.modules if m.split('.')[0] == 'hil_sim')\n"
            "print(len([m for m in sys.modules if m.startswith('js2io.')]), bad)\n")
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, check=True).stdout
    n, bad = out.split(" ", 1)
    assert int(n) >= 10 and bad.strip() == "[]", out


def test_rigs_are_found_by_name():
    from js2io.rigs import available
    have = available()
    assert {"sim", "sim-direct", "sim-process"} <= set(have), have
    assert all(ep.value.startswith("hil_sim.") for k, ep in have.items() if k.startswith("sim"))


def test_unknown_rig_is_one_line_exit_2(tmp_path, capsys):
    from js2io.cli import main
    rc = main(["--sim", "nope", "--trial", "static", "-o", str(tmp_path / "x.mcap"), "--no-progress"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2
    assert len(err) == 1 and "--sim nope" in err[0] and "sim-direct" in err[0], err
    assert not (tmp_path / "x.mcap").exists()


def test_sim_with_a_bus_is_refused(tmp_path, capsys):
    from js2io.cli import main
    rc = main(["--sim", "sim", "-i", "virtual", "--trial", "static", "-o", str(tmp_path / "x.mcap")])
    assert rc == 2 and "apply to the simulated drives only" in capsys.readouterr().err


def test_pdo_layout_is_the_eds_default():
    from js2io.pdo import read_layout
    lay = read_layout(ROBOT.eds_path)
    assert [p.name for p in lay.rpdos] == ["RPDO1", "RPDO2"] and [p.name for p in lay.tpdos] == ["TPDO1"]
    assert lay.feedback.objects == (0x6041, 0x6064, 0x6078) and lay.feedback.codec.format == "<Hih"
    assert lay.rpdos[0].cob_id(3) == 0x203 and lay.feedback.cob_id(3) == 0x183 and lay.sync_cob == 0x80
    assert lay.frame_bytes() == ([4, 4], [8])


def _edit_eds(src: Path, dest_folder: Path, edits: dict) -> Path:
    """Copy the robot folder and change DefaultValue lines of the given EDS sections."""
    shutil.copytree(src, dest_folder)
    eds = dest_folder / "drives.eds"
    lines, section = [], None
    for line in eds.read_text().splitlines():
        if line.startswith("["):
            section = line.strip("[]")
        if section in edits and line.startswith("DefaultValue="):
            line = f"DefaultValue={edits[section]}"
        lines.append(line)
    eds.write_text("\n".join(lines) + "\n")
    return dest_folder


def test_master_and_drives_follow_a_changed_layout(tmp_path):
    """TPDO1 re-ordered in the EDS (position first, then current, then statusword): the master maps, sends and reads
    the new layout, the simulated drives send it; the recorded trial is the same as with the original layout."""
    from hil_sim.canopen_inprocess import InProcessCanopen
    from js2io.session import run_trials
    folder = _edit_eds(ROBOT.folder, tmp_path / "robot",
                       {"1A00sub1": "0x60640020", "1A00sub2": "0x60780010", "1A00sub3": "0x60410010"})
    swapped = load_robot(folder)
    from js2io.pdo import read_layout
    assert read_layout(swapped.eds_path).feedback.codec.format == "<ihH"
    cfg = short_trials_yaml(tmp_path / "t.yaml")
    logs = []
    for k, robot in enumerate((ROBOT, swapped)):
        with InProcessCanopen(robot) as rig:
            res = run_trials(rig.group, robot, ["excitation"], tmp_path / f"{k}.mcap", trials_config=cfg)
        assert not res.aborted, res.text()
        logs.append(read_log(tmp_path / f"{k}.mcap"))
    a, b = logs
    assert len(a.feedback.t) == len(b.feedback.t) > 500
    np.testing.assert_array_equal(a.feedback.motor_position, b.feedback.motor_position)
    np.testing.assert_array_equal(a.feedback.status, b.feedback.status)
    np.testing.assert_array_equal(a.command.target_torque, b.command.target_torque)


def test_eds_without_the_feedback_objects_is_refused(tmp_path):
    from js2io.pdo import read_layout
    folder = _edit_eds(ROBOT.folder, tmp_path / "robot", {"1A00sub3": "0x00000000", "1A00sub0": "2"})
    with pytest.raises(ConfigError) as e:
        read_layout(folder / "drives.eds")
    assert "0x6078" in str(e.value) and "drives.eds" in str(e.value)


def test_sim_process_runs_a_trial(tmp_path, capsys):
    """--sim sim-process: js2-sim is a child process; the master talks to it over socketcand."""
    from js2io.cli import main
    out = tmp_path / "p.mcap"
    rc = main(["--sim", "sim-process", "--trial", "excitation", "-o", str(out), "--no-progress",
               "--config", str(short_trials_yaml(tmp_path / "t.yaml"))])
    err = capsys.readouterr().err
    assert rc == 0, err
    assert "own process" in err
    log = read_log(out)
    assert log.source == "hil_sim:canopen" and log.feedback.valid.all()
