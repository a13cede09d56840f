#!/usr/bin/env python3
"""How long js2-diagnose takes on a long session (issue 11's goal: a 4-minute, 500 Hz session in under 30 s on one
core), stage by stage.

1. the simulated Js-2 records the identification trials (no hidden effect) and js2-identify makes the model (once,
   cached in OUT);
2. one excitation + validation recording at 500 Hz with a payload hidden (once, cached);
3. the session: that recording given ``--repeat`` times (default 8, about 4.3 minutes) as one session over several
   files (js2-diagnose MODEL LOG LOG ... joins them, each filtered on its own) — the same work per sample as one long
   recording;
4. diagnose it in this process, timing each stage: read + join, residual (prediction, regressor), the search's
   per-sample pinocchio terms and backlash link simulation (made once, at the search's first use), the search (every
   candidate, every step), locate + outputs.

Prints CPU seconds per stage (``time.process_time``: the process's own CPU time, numpy's threads limited to one, so
other jobs on the machine do not count) and wall seconds, the total scaled to 4 minutes and its ratio to the 30 s
goal, and the peak memory. ``--per-kind``: also the search's CPU seconds per candidate kind and ladder step (through
the search's progress hook), and the folder the ``diagnosis`` package was imported from (to compare two versions of
the code on the same session: run this script with PYTHONPATH set to the other version's checkout).

    .venv/bin/python scripts/bench_diagnose_speed.py [--repeat 8] [--out runs/bench_diagnose_speed] [--per-kind]
"""
from __future__ import annotations

import argparse
import os
import resource
import sys
import time
from pathlib import Path

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")          # one core, as the goal says

GOAL_S = 30.0


def prepare(out: Path) -> tuple[Path, Path]:
    from bench_diagnose import bench_model
    from hil_sim.direct import DirectDriveGroup
    from hil_sim.plant import Plant
    from js2io.session import run_trials
    from js2spec.robot import load_robot

    robot = load_robot("js2")
    model = bench_model(out, robot)
    if model is None:
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
    ap.add_argument("--per-kind", action="store_true", help="also CPU seconds per candidate kind and ladder step")
    a = ap.parse_args(argv)
    if a.repeat < 1:
        print("bench_diagnose_speed: error: --repeat must be at least 1", file=sys.stderr)
        return 2
    model, rec = prepare(a.out)

    from diagnosis.library import _link_response, _mass_column, _rnea_dq
    from diagnosis.locate import locate
    from diagnosis.report import write_outputs
    from diagnosis.residual import residual_data
    from diagnosis.run import DiagnosisResult
    from diagnosis.search import MismatchSearch
    from js2spec.log import join_logs, read_log
    from js2spec.model import load_model

    cpu, wall = {}, {}

    def stage(name, t_cpu, t_wall):
        cpu[name] = time.process_time() - t_cpu
        wall[name] = time.perf_counter() - t_wall
        return time.process_time(), time.perf_counter()

    c0, w0 = time.process_time(), time.perf_counter()
    mdl = load_model(model)
    log = join_logs([read_log(rec) for _ in range(a.repeat)])
    c, w = stage("read + join", c0, w0)
    rd = residual_data(mdl, log)
    c, w = stage("residual (prediction, regressor, split)", c, w)
    _mass_column(rd, 0), _rnea_dq(rd, 0)          # cached in rd: the search would make them at its first use
    c, w = stage("  M(q), d tau/d q per sample (pinocchio)", c, w)
    _link_response(rd, 0)
    c, w = stage("  backlash link simulation", c, w)
    per_kind = {}

    def progress(tasks, desc):          # CPU seconds of each candidate, summed per kind (band) and ladder step
        for term, j in tasks:
            t0 = time.process_time()
            yield term, j
            key = (term.kind + (" (unfiltered)" if term.band == "wide" else ""), desc)
            per_kind[key] = per_kind.get(key, 0.0) + time.process_time() - t0

    search = MismatchSearch(progress=progress if a.per_kind else None).fit(rd)
    c, w = stage("  search (every candidate, every step)", c, w)
    res = DiagnosisResult(model=mdl, log_path=rec, log_paths=[rec] * a.repeat, rd=rd, search=search,
                          location=locate(rd, search))
    write_outputs(res, a.out / "diagnosis")
    stage("locate + outputs (report.html)", c, w)
    total = sum(cpu.values())
    span = float(rd.t[-1] - rd.t[0])
    print(f"session: {a.repeat} files, {len(rd.t)} samples at {rd.fs:g} Hz = {span / 60:.2f} min, "
          f"{rd.n} joints; {search.tried_} candidates scored in {len(search.rankings_)} step(s)")
    print(f"  {'stage':<42} {'CPU s':>7} {'wall s':>7}")
    for name in cpu:
        print(f"  {name:<42} {cpu[name]:7.1f} {wall[name]:7.1f}")
    per_4min = total * 240.0 / span
    print(f"total CPU {total:.1f} s (wall {sum(wall.values()):.1f} s); scaled to a 4-minute session "
          f"{per_4min:.1f} CPU s = {per_4min / GOAL_S:.2f}x the {GOAL_S:g} s goal ({'met' if per_4min <= GOAL_S else 'not met'})")
    if a.per_kind:
        import diagnosis
        steps = sorted({step for _, step in per_kind})
        kinds = sorted({kind for kind, _ in per_kind}, key=lambda k: -sum(v for (kk, _), v in per_kind.items() if kk == k))
        print(f"search CPU s per candidate kind (code: {Path(diagnosis.__file__).resolve().parent})")
        print(f"  {'kind':<30}" + "".join(f" {st.replace('diagnosis ', ''):>7}" for st in steps) + f" {'all':>7}")
        for kind in kinds:
            row = [per_kind.get((kind, st), 0.0) for st in steps]
            print(f"  {kind:<30}" + "".join(f" {v:7.2f}" for v in row) + f" {sum(row):7.2f}")
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2 ** 20      # KiB -> GiB (Linux)
    print(f"peak memory {peak:.2f} GiB")
    print(f"verdict: {res.verdict()}")
    print(f"machine: load average {os.getloadavg()[0]:.1f} (1 min) during the run; {os.cpu_count()} CPUs (CPU "
          "seconds are this process's own; a loaded machine still inflates them somewhat: shared caches)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
