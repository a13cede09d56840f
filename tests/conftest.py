"""Fixtures shared across test modules."""
from __future__ import annotations

import pytest

from fixtures_id_sim import REAL, prove_diagnosis_real


@pytest.fixture(scope="session")
def kuka_diag(tmp_path_factory):
    """The three KUKA recordings imported and the model from the plain `js2-identify kuka_1.mcap` (prove steps 1-2),
    made once for every module that diagnoses them (read-only: tests write their own files elsewhere)."""
    if not (REAL / "kuka_lwr4").is_dir():
        pytest.skip(f"real-arm recordings not found at {REAL}")
    prove = prove_diagnosis_real()
    work = tmp_path_factory.mktemp("kuka_diag")
    logs = prove.import_logs(REAL, work)
    model = prove.identify(logs[0], work / "model")
    return {"work": work, "logs": logs, "model": model}
