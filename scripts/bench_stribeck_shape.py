#!/usr/bin/env python3
"""How well js2-diagnose reads a Stribeck hump's shape and velocity: simulator cases that each conceal one hump.

Case k (seed k, fixed) is a ``bench_diagnose.py`` case (its own excitation and validation trajectories, sample rate
250, 500 or 1000 Hz and host controller gains) with its effects replaced by one Stribeck hump drawn as that bench
draws them (``bench_diagnose.draw_effect``: a random joint, v_s 2-8 rad/s at the motor, shape 1 or 2). The
simulator records it, js2-diagnose (defaults) diagnoses it with the bench's model, and the script prints per case
the ladder's reading (v_s on 13 points with shape 2: what the diagnosis reported until stop 39, the candidate the
ladder accepted) and the refined one (v_s on 49 points, with shape 1 and shape 2, the shape reported where the
select rows prefer it by 20:1: ``diagnosis.library.Stribeck.refined``), then the summary: humps named, shapes right,
shapes resolved (and right), v_s error median and max of both readings.

    .venv/bin/python scripts/bench_stribeck_shape.py [--first 0] [--cases 40] [--out runs/bench_stribeck_shape]
        [--json docs/bench/...json]

The recordings stay in OUT (``strib_NNN.mcap``); a second run diagnoses them again (after a change to the
diagnosis). Simulating a case takes about 10 s, diagnosing it 10-40 s on one core.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

DRAW_SEED = 50_000      # the hump's own random stream: seed DRAW_SEED + k (the trajectory's is the bench's, 1000 + k)


def draw(seed: int, robot, base_cfg: dict) -> dict:
    import bench_diagnose as B

    case = B.draw_case(seed, robot.drives.n, base_cfg)
    case["effects"] = [B.draw_effect(np.random.default_rng(DRAW_SEED + seed), "stribeck", robot.drives.n)]
    return case


def readings(res, joint: int) -> dict | None:
    """The named reading and the ladder's (the Stribeck candidate on ``joint`` in the ranking of the step that
    accepted it, before :meth:`Stribeck.refined`); None when no Stribeck was named on that joint."""
    from diagnosis.library import Stribeck

    named = [s for s in res.accepted if s.fitted.kind == "stribeck" and s.fitted.joint == joint]
    if not named:
        return None
    h = named[0].fitted.hyper
    # a kind accepted on a joint is not tried there again: the last ranking holding it is the step that accepted it
    ladder = [s.fitted.hyper for ranking in res.search.rankings_ for s in ranking
              if s.fitted.kind == "stribeck" and s.fitted.joint == joint][-1]
    evidence = float(h[2]) if len(h) > 2 else float("nan")
    return {"velocity": float(h[0]), "shape": float(h[1]), "evidence": evidence,
            "resolved": bool(evidence >= Stribeck.RESOLVED),
            "ladder_velocity": float(ladder[0]), "ladder_shape": float(ladder[1])}


def summary(rows: list[dict]) -> dict:
    named = [r for r in rows if r["read"] is not None]
    err = [abs(r["read"]["velocity"] / r["truth"]["velocity"] - 1) for r in named]
    err_ladder = [abs(r["read"]["ladder_velocity"] / r["truth"]["velocity"] - 1) for r in named]
    right = [r for r in named if r["read"]["shape"] == r["truth"]["shape"]]
    resolved = [r for r in named if r["read"]["resolved"]]
    return {"cases": len(rows), "named": len(named), "shape_right": len(right),
            "ladder_shape_right": sum(r["read"]["ladder_shape"] == r["truth"]["shape"] for r in named),
            "resolved": len(resolved), "resolved_right": sum(r["read"]["shape"] == r["truth"]["shape"] for r in resolved),
            "velocity_error_median": float(np.median(err)) if err else float("nan"),
            "velocity_error_max": float(np.max(err)) if err else float("nan"),
            "ladder_velocity_error_median": float(np.median(err_ladder)) if err else float("nan"),
            "ladder_velocity_error_max": float(np.max(err_ladder)) if err else float("nan")}


def print_summary(s: dict) -> None:
    print(f"humps named: {s['named']} of {s['cases']}")
    print(f"shape right: {s['shape_right']} of {s['named']} (the ladder's shape 2: {s['ladder_shape_right']}); "
          f"resolved (20:1): {s['resolved']}, right {s['resolved_right']}")
    print(f"v_s error: median {s['velocity_error_median']:.1%}, max {s['velocity_error_max']:.1%} "
          f"(the ladder's: median {s['ladder_velocity_error_median']:.1%}, max {s['ladder_velocity_error_max']:.1%})")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--first", type=int, default=0, help="first case (seed)")
    ap.add_argument("--cases", type=int, default=40, help="number of cases")
    ap.add_argument("--out", type=Path, default=Path("runs/bench_stribeck_shape"),
                    help="recordings and the model (made once, as bench_diagnose.py makes it)")
    ap.add_argument("--model", type=Path, default=None, help="model directory (default: OUT/model, made if missing)")
    ap.add_argument("--json", type=Path, default=None, help="also write the rows and the summary here")
    a = ap.parse_args(argv)
    if a.cases < 1:
        print("bench_stribeck_shape: error: --cases must be at least 1", file=sys.stderr)
        return 2
    if a.model is not None and not (a.model / "model.yaml").is_file():
        print(f"bench_stribeck_shape: error: {a.model} holds no model.yaml (give a js2-identify output folder, or "
              "leave --model out to have OUT/model made)", file=sys.stderr)
        return 2
    import bench_diagnose as B

    from diagnosis.run import diagnose
    from js2io.session import _default_trials
    from js2io.trials import load_trials_config
    from js2spec.robot import load_robot

    robot = load_robot("js2")
    base_cfg = load_trials_config(robot.trials_path or _default_trials())
    a.out.mkdir(parents=True, exist_ok=True)
    model = a.model or B.bench_model(a.out, robot)
    if model is None:
        return 1
    rows = []
    for seed in range(a.first, a.first + a.cases):
        case = draw(seed, robot, base_cfg)
        e = case["effects"][0]
        rec = a.out / f"strib_{seed:03d}.mcap"
        if not rec.is_file():
            B.record(robot, rec, case["effects"], case["trials"], seed, case["cycle_hz"])
        res = diagnose(model, rec)
        j = e["joints"][0]
        row = {"seed": seed, "cycle_hz": case["cycle_hz"], "joint": j,
               "truth": {"velocity": e["velocity"], "shape": e["shape"]}, "read": readings(res, j),
               "named": [[s.fitted.kind, s.fitted.joint] for s in res.accepted]}
        rows.append(row)
        r = row["read"]
        what = ("not named" if r is None else
                f"read v_s {r['velocity']:.3g} shape {r['shape']:g} ({'resolved' if r['resolved'] else 'not resolved'},"
                f" ln LR {r['evidence']:.1f}); ladder v_s {r['ladder_velocity']:.3g} shape {r['ladder_shape']:g}")
        print(f"case {seed:3d}: {case['cycle_hz']:6.0f} Hz j{j + 1} v_s {e['velocity']:.3g} shape {e['shape']:g}: {what}",
              flush=True)
    s = summary(rows)
    print_summary(s)
    if a.json:
        a.json.write_text(json.dumps({"summary": s, "rows": rows}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
