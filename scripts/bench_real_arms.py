#!/usr/bin/env python3
"""Held-out torque error of js2's exported model beside the textbook fit and the published models, on every arm in
../shared/data/real plus the simulated Js-2. One table, per joint and overall.

    .venv/bin/python scripts/bench_real_arms.py [DATA_DIR] [--json OUT.json]

Each arm goes through the plain product path, as a new user would run it (no tuning flags):
  Staubli TX40   js2-import (maintainers' split: fit rows 0-24750, validation rows 29250-45000) -> js2-identify LOG
  KUKA LWR4+     js2-import measurements_1 and _3 -> js2-identify kuka_1.mcap --validate kuka_3.mcap
  Js-2 (sim)     a simulator session (static, velocity, acceleration, validation trials) -> js2-identify LOG
Models, all evaluated on the same held-out samples through the same filters:
  js2            the exported model (robot_identified.urdf + model.yaml: physically consistent links, J_a, friction)
  textbook OLS   js2's built-in baseline: plain OLS on the base regressor with Coulomb + viscous friction, same fit
                 samples (``validation.baseline`` in model.yaml)
  published      what the arm's authors published (FIGAROH, FloBaRoID, Gaz et al.), or the simulator's truth
Figure: relative error ||tau_pred - tau_meas|| / ||tau_meas|| (per joint: that joint's column; overall: all joints),
in %, on the filtered torque of the held-out samples. The README's "Real arms" table is this script's output,
pinned by tests/test_bench_real_arms.py at the tolerance stated there.
"""
from __future__ import annotations

import os

for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")
import argparse
import json
import sys
import tempfile
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
DEFAULT_DATA = REPO.parent / "shared" / "data" / "real"


def _row(model: str, pred, meas) -> dict:
    from identification.pipeline import relative_error

    rel, overall = relative_error(pred, meas)
    return {"model": model, "joints": [100 * float(x) for x in rel], "overall": 100 * overall}


def _ident_rows(ident) -> list[dict]:
    v = ident.validation
    meas = v["measured"]
    exp = v[v["exported"]]["pred"]
    return [_row("js2 (exported model)", exp, meas), _row("textbook OLS (js2 baseline)", v["baseline"]["pred"], meas)]


def bench_tx40(data: Path, work: Path) -> dict:
    from identification.examples.real_arms import import_tx40, tx40_published
    from identification.pipeline import identify
    from identification.reference import published_friction, reference_prediction

    ident = identify([import_tx40(data, work / "tx40.mcap")])
    rows = _ident_rows(ident)
    pub = tx40_published(data, ident.logs[0].drives)
    p, m, _ = reference_prediction(ident, fixed=pub["fixed"], refit=False)
    rows.append(_row("FIGAROH published drive terms + CAD inertials", p, m))
    p, m, _ = reference_prediction(ident, refit=True)
    rows.append(_row("CAD inertials + drive terms refitted", p, m))
    return {"arm": "Stäubli TX40 (motor torques, 5 kHz; maintainers' split)", "joints": list(ident.arm.joints),
            "rows": rows, "notes": ident.notes}


def bench_kuka(data: Path, work: Path) -> dict:
    from identification.examples.real_arms import import_kuka
    from identification.pipeline import IdentifyOptions, identify
    from identification.reference import published_friction, reference_prediction

    logs = import_kuka(data, work)
    ident = identify([logs[0]], IdentifyOptions(validate_paths=(str(logs[2]),)))
    rows = _ident_rows(ident)
    pubdir = data / "kuka_lwr4" / "published"
    for name, path in (("FloBaRoID identified URDF + drive terms refitted", pubdir / "kuka_lwr4_identified.urdf"),
                       ("Gaz et al. 2016 URDF + drive terms refitted", pubdir / "kuka_lwr4_gaz.urdf"),
                       ("CAD URDF + drive terms refitted", data / "kuka_lwr4" / "kinematics" / "kuka_lwr4.urdf")):
        p, m, _ = reference_prediction(ident, path.read_text(), refit=True)
        rows.append(_row(name, p, m))
    fixed = published_friction((pubdir / "kuka_lwr4_identified.urdf").read_text(), list(ident.arm.joints))
    p, m, _ = reference_prediction(ident, (pubdir / "kuka_lwr4_identified.urdf").read_text(), fixed=fixed, refit=True)
    rows.append(_row("FloBaRoID identified URDF as published (its friction; offsets refitted)", p, m))
    return {"arm": "KUKA LWR4+ (joint torque sensors, 200 Hz; fit file 1, validate file 3)",
            "joints": list(ident.arm.joints), "rows": rows, "notes": ident.notes}


def bench_js2_sim(work: Path) -> dict:
    from hil_sim.direct import DirectDriveGroup
    from hil_sim.truth import load_truth
    from identification.pipeline import identify
    from identification.reference import reference_prediction
    from js2io.session import run_trials
    from js2spec.robot import load_robot

    robot = load_robot("js2")
    path = work / "js2_sim.mcap"
    with DirectDriveGroup(robot, seed=0) as group:
        res = run_trials(group, robot, ["static", "velocity", "acceleration", "validation"], path)
    if res.aborted:
        raise RuntimeError(f"simulated session aborted: {res.reason}")
    ident = identify([path])
    rows = _ident_rows(ident)
    tr = load_truth(robot)
    fixed = {}
    for k in range(ident.arm.n):
        fixed.update({f"Ja_{k + 1}": tr.motor_inertia[k], f"B_{k + 1}": tr.viscous[k], f"fc_{k + 1}": tr.coulomb[k]})
    p, m, _ = reference_prediction(ident, fixed=fixed, refit=False)
    rows.append(_row("simulator truth (URDF inertials + sim_truth drive terms)", p, m))
    return {"arm": "Js-2 (simulated; paper's trials, mixed method)", "joints": list(ident.arm.joints), "rows": rows,
            "notes": ident.notes}


def run(data: Path, work: Path, arms=("tx40", "kuka", "js2")) -> list[dict]:
    out = []
    if "tx40" in arms:
        out.append(bench_tx40(data, work))
    if "kuka" in arms:
        out.append(bench_kuka(data, work))
    if "js2" in arms:
        out.append(bench_js2_sim(work))
    return out


def markdown(results: list[dict]) -> str:
    width = max(len(r["joints"]) for r in results)
    head = "| arm | model | " + " | ".join(f"j{k + 1}" for k in range(width)) + " | overall | / OLS |"
    lines = [head, "|" + " --- |" * (width + 4)]
    for res in results:
        base = next(r["overall"] for r in res["rows"] if r["model"].startswith("textbook OLS"))
        for i, r in enumerate(res["rows"]):
            cells = [f"{x:.2f}" for x in r["joints"]] + [""] * (width - len(r["joints"]))
            arm = res["arm"] if i == 0 else ""
            name = f"**{r['model']}**" if r["model"].startswith("js2") else r["model"]
            lines.append(f"| {arm} | {name} | " + " | ".join(cells) + f" | {r['overall']:.2f} | "
                         f"{r['overall'] / base:.2f} |")
    return "\n".join(lines)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("data", nargs="?", type=Path, default=DEFAULT_DATA)
    p.add_argument("--json", type=Path, help="also write the figures as JSON")
    p.add_argument("--arms", default="tx40,kuka,js2", help="comma-separated subset of tx40, kuka, js2")
    a = p.parse_args(argv)
    arms = tuple(x.strip() for x in a.arms.split(","))
    if ({"tx40", "kuka"} & set(arms)) and not a.data.is_dir():
        print(f"bench_real_arms: error: {a.data}: data folder not found (give the folder holding staubli_tx40/ and "
              f"kuka_lwr4/)", file=sys.stderr)
        return 2
    with tempfile.TemporaryDirectory(prefix="js2_bench_real_") as tmp:
        results = run(a.data, Path(tmp), arms)
    print("Relative held-out torque error, % (lower is better); / OLS = overall error / the textbook OLS's\n")
    print(markdown(results))
    if a.json:
        a.json.write_text(json.dumps(results, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
