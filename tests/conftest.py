"""Fixtures shared across test modules."""
from __future__ import annotations

import json
import os
import shutil
import tempfile
from pathlib import Path

import pytest

import shared_data
from fixtures_id_sim import REAL, prove_diagnosis_real


def pytest_configure(config):
    """The run's shared folder of generated data (``shared_data``), made by the process that starts the run (a
    pytest-xdist worker inherits it through the environment)."""
    if hasattr(config, "workerinput") or os.environ.get(shared_data.ENV):
        return
    config._js2_shared = tempfile.mkdtemp(prefix="js2_tests_")
    os.environ[shared_data.ENV] = config._js2_shared


def pytest_unconfigure(config):
    path = getattr(config, "_js2_shared", None)
    if path:
        os.environ.pop(shared_data.ENV, None)
        shutil.rmtree(path, ignore_errors=True)


@pytest.fixture(scope="session")
def kuka_diag():
    """The three KUKA recordings imported and the model from the plain `js2-identify kuka_1.mcap` (prove steps 1-2),
    made once for every module that diagnoses them (read-only: tests write their own files elsewhere)."""
    if not (REAL / "kuka_lwr4").is_dir():
        pytest.skip(f"real-arm recordings not found at {REAL}")
    prove = prove_diagnosis_real()
    work = shared_data.folder("kuka_diag")
    made = work / "made.json"
    with shared_data.build_once(made) as build:          # once per run, pytest-xdist's workers included
        if build:
            logs = prove.import_logs(REAL, work)
            model = prove.identify(logs[0], work / "model")
            made.write_text(json.dumps({"logs": [str(p) for p in logs], "model": str(model)}))
    paths = json.loads(made.read_text())
    return {"work": work, "logs": [Path(p) for p in paths["logs"]], "model": Path(paths["model"])}
