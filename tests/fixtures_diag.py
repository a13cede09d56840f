"""Models and recordings for the diagnosis tests: a model identified from a clean simulated session, and simulator
recordings (excitation + validation trials) with hidden effects. Built once per test run (``shared_data``)."""
import functools
import json
from pathlib import Path

from fixtures_id_sim import sim_session
from shared_data import build_once, folder, key


@functools.lru_cache(maxsize=None)
def clean_model() -> Path:
    from identification.cli.identify import main as identify_main

    out = folder("diag_tests") / "model"
    with build_once(out) as build:
        if build:
            rc = identify_main([str(sim_session()), "-o", str(out), "--no-report", "-q"])
            assert rc == 0 and (out / "model.yaml").is_file()
    return out


@functools.lru_cache(maxsize=None)
def recording(effects_json: str) -> Path:
    """excitation + validation trials on the simulator with the given (hidden) effects (a JSON list)."""
    from hil_sim.direct import DirectDriveGroup
    from hil_sim.plant import Plant
    from js2io.session import run_trials
    from js2spec.robot import load_robot

    path = folder("diag_tests") / f"rec_{key(effects_json)}.mcap"
    with build_once(path) as build:
        if build:
            robot = load_robot("js2")
            plant = Plant(robot, seed=5, effects=json.loads(effects_json))
            with DirectDriveGroup(robot, plant=plant, seed=5) as group:
                res = run_trials(group, robot, ["excitation", "validation"], path)
            assert not res.aborted, res.reason
    return path
