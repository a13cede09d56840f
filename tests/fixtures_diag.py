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


def bench_recording(seed: int, folder: Path) -> tuple[dict, Path]:
    """Bench case ``seed`` of scripts/bench_diagnose.py (its own trajectory, sample rate and effects), recorded by the
    simulator into ``folder`` as the bench records it: (the drawn case, the recording's path)."""
    import copy
    import sys

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))
    import bench_diagnose as bench
    from js2io.session import _default_trials
    from js2io.trials import load_trials_config
    from js2spec.robot import load_robot

    robot = load_robot("js2")
    base = load_trials_config(robot.trials_path or _default_trials())
    case = bench.draw_case(seed, 6, base)
    cfg = copy.deepcopy(base)
    cfg.update(copy.deepcopy(case["trials"]))
    rec = folder / f"case_{seed:03d}.mcap"
    bench.record(robot, rec, case["effects"], cfg, seed=seed, cycle_hz=case["cycle_hz"])
    return case, rec
