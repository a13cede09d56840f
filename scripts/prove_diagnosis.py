#!/usr/bin/env python3
"""Prove the mismatch diagnosis on recordings where one effect is concealed, and print the table of the README.

1. the simulated Js-2 runs the identification trials (static, velocity, acceleration, validation) with no hidden
   effect; js2-identify makes the model (mixed method);
2. for each effect kind, the simulator records an excitation and a validation trajectory with that effect on one
   joint (the model knows nothing of it);
3. js2-diagnose fits its candidate terms on the excitation and scores them on the validation trajectory.

    .venv/bin/python scripts/prove_diagnosis.py [--out runs/prove_diagnosis] [--kinds stribeck cogging ...]
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

CASES = [
    ("none", None, {}),
    ("stribeck", 1, {"velocity": 4.0}),
    ("cogging", 2, {"amplitude": 0.004, "periods_per_rev": 2}),
    ("payload_change", 5, {"mass": 0.3, "com": [0.05, 0.0, 0.0]}),
    ("thermal_drift", 0, {"heating": 5.0, "time_constant": 15.0, "friction_per_kelvin": 0.05}),
    ("thermal_drift", 0, {"friction_power_heating": 5.0, "time_constant": 20.0, "friction_per_kelvin": 0.05}),
    ("load_dependent_friction", 1, {"coefficient": 0.15}),
    ("asymmetric_friction", 0, {"negative_scale": 1.5}),
    ("joint_elasticity", 1, {"stiffness": 1500.0, "damping": 3.0}),
    ("backlash", 0, {"width": 0.03, "stiffness": 3000.0, "damping": 3.0}),
]


def record(robot, path: Path, trials, effects, seed):
    from hil_sim.direct import DirectDriveGroup
    from hil_sim.plant import Plant
    from js2io.session import run_trials

    plant = Plant(robot, seed=seed, effects=effects)
    with DirectDriveGroup(robot, plant=plant, seed=seed) as group:
        res = run_trials(group, robot, trials, path)
    if res.aborted:
        raise SystemExit(f"simulation aborted: {res.reason}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default="runs/prove_diagnosis", help="output folder")
    ap.add_argument("--kinds", nargs="+", help="only these cases (default: all, 'none' = a clean recording)")
    ap.add_argument("--seed", type=int, default=5)
    args = ap.parse_args(argv)
    from diagnosis.report import write_outputs
    from diagnosis.run import diagnose
    from identification.cli.identify import main as identify_main
    from js2spec.robot import load_robot

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    robot = load_robot("js2")
    session = out / "clean_session.mcap"
    t0 = time.time()
    if not session.is_file():
        print("recording the clean identification session ...", flush=True)
        record(robot, session, ["static", "velocity", "acceleration", "validation"], [], args.seed)
    model = out / "model"
    if not (model / "model.yaml").is_file():
        print("identifying the model (mixed method) ...", flush=True)
        if identify_main([str(session), "-o", str(model), "-q"]) != 0:
            return 1
    rows = []
    for kind, joint, params in CASES:
        if args.kinds and kind not in args.kinds:
            continue
        eff = [] if joint is None else [{"kind": kind, "joints": [joint], **params}]
        label = kind + ("_friction_power" if "friction_power_heating" in params else "")
        rec = out / f"recording_{label}.mcap"
        if not rec.is_file():
            record(robot, rec, ["excitation", "validation"], eff, args.seed)
        t1 = time.time()
        res = diagnose(model, rec)
        write_outputs(res, out / f"diagnosis_{label}")
        found = res.findings()[0] if res.findings() else None
        motor = None if found is None else found["effect"]["joints"][0]
        if found is not None and found["kind"] == "payload_change":
            motor = max(range(robot.drives.n),
                        key=lambda i: found["holdout_rms_before"][i] - found["holdout_rms_after"][i])
        rows.append({
            "concealed": kind if joint is None else f"{label} on {robot.drives.joints[joint]}",
            "truth": params,
            "named": "nothing" if found is None else f"{found['kind']} on {found['joint']}",
            "found": {} if found is None else {k: v for k, v in found["effect"].items() if k not in ("kind", "joints")},
            "holdout_rms_before": None if found is None else float(found["holdout_rms_before"][motor]),
            "holdout_rms_after": None if found is None else float(found["holdout_rms_after"][motor]),
            "seconds": round(time.time() - t1, 1),
        })
        r = rows[-1]
        drop = "" if found is None else (f"{r['holdout_rms_before'] * 1e3:.2f} -> {r['holdout_rms_after'] * 1e3:.2f} "
                                         f"mN m")
        print(f"{r['concealed']:<34} named: {r['named']:<30} {drop:<22} found {json.dumps(r['found'], default=str)}",
              flush=True)
    (out / "summary.json").write_text(json.dumps(rows, indent=1, default=str))
    print(f"done in {time.time() - t0:.0f} s -> {out}/summary.json, {out}/diagnosis_*/report.html")
    return 0


if __name__ == "__main__":
    sys.exit(main())
