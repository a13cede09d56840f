"""The bad-input corpus: every CLI x every kind of bad file -> one line naming the file and what to do, exit 2
(or, for damaged logs, the documented recovery that says so). Never a traceback, never exit 1 (which means
"stopped safely" / "verdict failed" to scripts).

Runs the CLIs' `main(argv)` in-process (the same code as the console scripts) so the corpus stays fast.
"""
from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from js2spec.robot import resolve_robot_folder

from fixtures_id_sim import synthetic_log

JS2 = resolve_robot_folder("js2")
RANDOM = np.random.default_rng(7).integers(0, 256, 4096, dtype=np.uint8).tobytes()
LATIN1 = "joint: Gelenk \u00e4\u00f6\u00fc, \u00b0C\n".encode("latin-1")

BAD_FILES = {   # kind -> how to make it at `path`
    "missing": lambda p: None,
    "empty": lambda p: p.write_bytes(b""),
    "directory": lambda p: p.mkdir(),
    "random bytes": lambda p: p.write_bytes(RANDOM),
    "non-UTF-8": lambda p: p.write_bytes(LATIN1),
}


def _one_line(capsys, rc, prog, must_name):
    out = capsys.readouterr()
    err = out.err.strip()
    assert rc == 2, f"exit {rc} (want 2)\n{out.out}\n{out.err}"
    assert "Traceback" not in out.err + out.out, out.err
    lines = [ln for ln in err.splitlines() if ln.startswith(f"{prog}: error:")]
    assert len(lines) == 1, err
    assert str(must_name) in lines[0], f"the error does not name {must_name}: {lines[0]}"
    return lines[0]


# ---------------------------------------------------------------------------------------------- robot folders
ROBOT_FILES = ["robot.urdf", "drives.yaml", "trials.yaml", "sim_truth.yaml", "drives.eds"]


@pytest.mark.parametrize("name", ROBOT_FILES)
@pytest.mark.parametrize("kind", ["empty", "directory", "random bytes", "non-UTF-8", "missing"])
def test_robot_folder_file(tmp_path, capsys, name, kind):
    from js2io.cli import main
    folder = tmp_path / "arm"
    shutil.copytree(JS2, folder)
    target = folder / name
    target.unlink()
    BAD_FILES[kind](target)
    if kind == "missing" and name in ("trials.yaml", "sim_truth.yaml", "drives.eds"):
        pytest.skip(f"{name} is optional in a robot folder (defaults or no simulator)")
    # the simulator's truth and the EDS are read when the (simulated) drives come up, not by --dry-run
    run = (["-o", str(tmp_path / "x.mcap"), "--no-progress"] if name in ("sim_truth.yaml", "drives.eds")
           else ["--dry-run"])
    rc = main(["--robot", str(folder), "--trial", "static", *run])
    line = _one_line(capsys, rc, "js2-acquire", folder)
    if kind == "non-UTF-8":
        assert "UTF-8" in line


def test_unknown_robot(capsys):
    from js2io.cli import main
    rc = main(["--robot", "no-such-arm", "--trial", "static", "--dry-run"])
    _one_line(capsys, rc, "js2-acquire", "no-such-arm")


# ---------------------------------------------------------------------------------------------- logs
@pytest.fixture(scope="module")
def good_log(tmp_path_factory):
    return synthetic_log(tmp_path_factory.mktemp("good") / "good.mcap", seconds=4.0)


def _bad_log(tmp_path, kind, good):
    p = tmp_path / "bad.mcap"
    if kind in BAD_FILES:
        BAD_FILES[kind](p)
    elif kind == "not js2 (other MCAP)":
        from mcap.writer import Writer
        with open(p, "wb") as f:
            w = Writer(f)
            w.start()
            w.finish()
    elif kind == "truncated header":
        p.write_bytes(Path(good).read_bytes()[:200])
    return p


LOG_KINDS = ["missing", "empty", "directory", "random bytes", "non-UTF-8", "not js2 (other MCAP)", "truncated header"]


@pytest.mark.parametrize("kind", LOG_KINDS)
def test_identify_bad_log(tmp_path, capsys, good_log, kind):
    from identification.cli.identify import main
    p = _bad_log(tmp_path, kind, good_log)
    rc = main([str(p), "-o", str(tmp_path / "out"), "-q", "--no-report"])
    _one_line(capsys, rc, "js2-identify", p)


@pytest.mark.parametrize("kind", LOG_KINDS)
def test_repair_bad_log(tmp_path, capsys, good_log, kind):
    from js2spec.repair import main
    p = _bad_log(tmp_path, kind, good_log)
    rc = main([str(p), "-o", str(tmp_path / "r.mcap")])
    if kind in ("not js2 (other MCAP)", "truncated header"):
        assert rc == 0       # an MCAP, however little it holds, can be rewritten complete
        capsys.readouterr()
        return
    _one_line(capsys, rc, "js2-repair", p)


@pytest.mark.parametrize("kind", ["missing", "empty", "directory", "random bytes", "non-UTF-8"])
def test_diagnose_bad_model(tmp_path, capsys, good_log, kind):
    from diagnosis.cli import main
    p = tmp_path / "model.yaml"
    BAD_FILES[kind](p)
    rc = main([str(p), str(good_log), "-o", str(tmp_path / "d"), "-q"])
    _one_line(capsys, rc, "js2-diagnose", p)


def test_identify_output_checked_first(tmp_path, capsys, good_log):
    from identification.cli.identify import main
    f = tmp_path / "afile"
    f.write_text("x")
    rc = main([str(good_log), "-o", str(f), "-q", "--no-report"])
    assert "is a file" in _one_line(capsys, rc, "js2-identify", f)


def test_identify_error_on_a_cut_log_mentions_the_cut(tmp_path, capsys, good_log):
    """The trial the pipeline needs was in the part a killed writer lost: the error says the log was cut."""
    from identification.cli.identify import main
    data = Path(good_log).read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: len(data) // 8])
    rc = main([str(cut), "-o", str(tmp_path / "o"), "-q", "--no-report"])
    line = _one_line(capsys, rc, "js2-identify", cut)
    assert "truncated" in line and "lost part" in line, line


def test_diagnose_output_checked_first(tmp_path, capsys, good_log):
    """`js2-diagnose -o` a file: refused in one line before the (long) diagnosis, not after it."""
    from diagnosis.cli import main
    f = tmp_path / "afile"
    f.write_text("x")
    rc = main([str(tmp_path / "no-model.yaml"), str(good_log), "-o", str(f), "-q"])
    assert "is a file" in _one_line(capsys, rc, "js2-diagnose", f)
    assert f.read_text() == "x"


@pytest.mark.parametrize("kind", LOG_KINDS)
def test_diagnose_bad_recording(tmp_path, capsys, good_log, kind):
    """A bad recording given to js2-diagnose (with a model it would otherwise need): one line naming it."""
    from diagnosis.cli import main
    p = _bad_log(tmp_path, kind, good_log)
    model = tmp_path / "model.yaml"
    model.write_text("joints: [j1]\n")      # never reached when the recording is refused first, else refused itself
    rc = main([str(model), str(p), "-o", str(tmp_path / "d"), "-q"])
    out = capsys.readouterr()
    assert rc == 2 and "Traceback" not in out.err and out.err.count("\n") == 1, out.err
    assert out.err.startswith("js2-diagnose: error:")


@pytest.mark.parametrize("kind", ["random bytes", "non-UTF-8", "text renamed .mcap", "cut"])
def test_diagnose_says_truncated_only_for_a_truncated_mcap(tmp_path, capsys, good_log, kind):
    """A file that is not MCAP at all (wrong magic bytes) is refused as such, with no note that it was cut (which
    would contradict it); a genuinely cut log still gets the note that what is missing may be in the lost part."""
    from diagnosis.cli import main
    p = tmp_path / "rec.mcap"
    if kind == "text renamed .mcap":
        p.write_text("t,q1,q2,tau1,tau2\n0.0,0.1,0.2,0.0,0.0\n")
    elif kind == "cut":
        data = Path(good_log).read_bytes()
        p.write_bytes(data[: len(data) // 8])
    else:
        BAD_FILES[kind](p)
    model = tmp_path / "model.yaml"        # loads; the recording is read before anyone compares the two
    model.write_text("joints: [j1]\nfriction: {static: [0.0], coulomb: [0.0], viscous: [0.0]}\n"
                     "motor_inertia: [0.0]\nbase_parameters: {names: [], values: [], std: []}\n")
    rc = main([str(model), str(p), "-o", str(tmp_path / "d"), "-q"])
    line = _one_line(capsys, rc, "js2-diagnose", p).replace(str(p), "FILE")    # the test's name is in the path
    if kind == "cut":
        assert "truncated" in line and "lost part" in line, line
    else:
        assert "not an MCAP file" in line and "truncated" not in line and "lost part" not in line, line


@pytest.mark.parametrize("name", ["robot.urdf", "drives.yaml", "sim_truth.yaml", "drives.eds"])
def test_sim_bad_robot_folder(tmp_path, capsys, name):
    from hil_sim.cli import main
    folder = tmp_path / "arm"
    shutil.copytree(JS2, folder)
    (folder / name).write_bytes(LATIN1)
    rc = main(["--robot", str(folder)])
    line = _one_line(capsys, rc, "js2-sim", folder)
    assert "UTF-8" in line
