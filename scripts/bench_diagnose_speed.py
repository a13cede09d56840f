#!/usr/bin/env python3
"""How long js2-diagnose takes on a long session (issue 11's goal: a 4-minute, 500 Hz session in under 30 s on one
core), stage by stage.

1. the simulated Js-2 records the identification trials (no hidden effect) and js2-identify makes the model (once,
   cached in OUT);
2. one excitation + validation recording at 500 Hz with a payload hidden (once, cached);
3. the session: that recording given ``--repeat`` times (default 8, about 4.3 minutes) as one session over several
   files (js2-diagnose MODEL LOG LOG ... joins them, each filtered on its own) — the same work per sample as one long
   recording;
4. diagnose it in this process, timing each stage: read + join, residual (prediction, regressor), search (every
   candidate, every step), locate + outputs.

Prints the figures and the ratio to the 30 s goal. Run it on a quiet machine: the figure is wall time of one core
(numpy's threads limited to one).

    .venv/bin/python scripts/bench_diagnose_speed.py [--repeat 8] [--out runs/bench_diagnose_speed]
"""
from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")          # one core, as the goal says

GOAL_S = 30.0


def prepare(out: Path) -> tuple[Path, Path]:
    from hil_sim.direct import DirectDriveGroup
    from hil_sim.plant import Plant
    from identification.cli.identify import main as identify_main
    from js2io.session import run_trials
    from js2spec.robot import load_robot

    robot = load_robot("js2")
    out.mkdir(parents=True, exist_ok=True)
    session = out / "clean_session.mcap"
    if not session.is_file():
        print("recording the clean identification session ...", flush=True)
        with DirectDriveGroup(robot, plant=Plant(robot, seed=0), seed=0) as group:
            run_trials(group, robot, ["static", "velocity", "acceleration", "validation"], session)
    model = out / "model"
    if not (model / "model.yaml").is_file():
        print("identifying the model ...", flush=True)
        if identify_main([str(session), "-o", str(model), "-q", "--no-report"]) != 0:
            raise SystemExit("js2-identify failed")
    rec = out / "payload_recording.mcap"
    if not rec.is_file():
        print("recording excitation + validation with a hidden 0.4 kg payload ...", flush=True)
        plant = Plant(robot, seed=3, effects=[{"kind": "payload_change", "joints": [5], "mass": 0.4,
                                               "com": [0.03, 0.0, 0.02]}])
        with DirectDriveGroup(robot, plant=plant, seed=3) as group:
            res = run_trials(group, robot, ["excitation", "validation"], rec, seed=3)
        if res.aborted:
            raise SystemExit(f"simulation aborted: {res.reason}")
    return model, rec


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeat", type=int, default=8, help="files in the session (default 8: about 4.3 minutes)")
    ap.add_argument("--out", type=Path, default=Path("runs/bench_diagnose_speed"))
    a = ap.parse_args(argv)
    if a.repeat < 1:
        print("bench_diagnose_speed: error: --repeat must be at least 1", file=sys.stderr)
        return 2
    model, rec = prepare(a.out)

    from diagnosis.locate import locate
    from diagnosis.report import write_outputs
    from diagnosis.residual import residual_data
    from diagnosis.run import DiagnosisResult
    from diagnosis.search import MismatchSearch
    from js2spec.log import join_logs, read_log
    from js2spec.model import load_model

    times = {}
    t0 = time.perf_counter()
    mdl = load_model(model)
    log = join_logs([read_log(rec) for _ in range(a.repeat)])
    times["read + join"] = time.perf_counter() - t0
    t = time.perf_counter()
    rd = residual_data(mdl, log)
    times["residual (prediction, regressor, split)"] = time.perf_counter() - t
    t = time.perf_counter()
    search = MismatchSearch().fit(rd)
    times["search (every candidate, every step)"] = time.perf_counter() - t
    t = time.perf_counter()
    res = DiagnosisResult(model=mdl, log_path=rec, log_paths=[rec] * a.repeat, rd=rd, search=search,
                          location=locate(rd, search))
    write_outputs(res, a.out / "diagnosis")
    times["locate + outputs (report.html)"] = time.perf_counter() - t
    total = time.perf_counter() - t0
    span = float(rd.t[-1] - rd.t[0])
    print(f"session: {a.repeat} files, {len(rd.t)} samples at {rd.fs:g} Hz = {span / 60:.2f} min, "
          f"{rd.n} joints; {search.tried_} candidates scored in {len(search.rankings_)} step(s)")
    for name, v in times.items():
        print(f"  {name:<42} {v:7.1f} s")
    per_4min = total * 240.0 / span
    print(f"total {total:.1f} s; scaled to a 4-minute session {per_4min:.1f} s = {per_4min / GOAL_S:.1f}x the "
          f"{GOAL_S:g} s goal ({'met' if per_4min <= GOAL_S else 'not met'})")
    print(f"verdict: {res.verdict()}")
    print(f"machine: load average {os.getloadavg()[0]:.1f} (1 min) during the run; {os.cpu_count()} CPUs")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
