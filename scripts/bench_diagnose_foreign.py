#!/usr/bin/env python3
"""Benchmark js2-diagnose on a simulator nobody on the diagnosis side wrote: confusion matrix, parameter errors.

``scripts/bench_diagnose.py`` draws its cases from js2's own simulator (hil_sim): its controller, trajectories,
friction law and arm are the ones the diagnosis was developed on. This bench draws them from ``foreign_sim``, a
second simulator written apart from hil_sim and from the diagnosis (it shares no physics code with either; see
foreign_sim/README.md):

- another arm: the Staubli TX40 (its URDF, gear ratios with the coupled wrist, FIGAROH's friction priors), the true
  arm's inertials and friction perturbed from the nominal URDF the user is given;
- Karnopp stiction; a computed-torque host controller or a drive-side cascade, per case;
- trajectories mixed from unrelated sines, point-to-point moves with rests and slow sweeps, per case;
- recording rates 100-1000 Hz, no trial labels (the diagnosis's documented time split), some sessions split over
  several files;
- the effects of js2spec.effects at random joints and sizes, 0-2 per case.

The user's path, with the plain commands' code: the clean identification recording is imported (js2-import) and
identified (js2-identify, defaults); each case is imported and diagnosed (js2-diagnose, defaults). A case's
*visibility* per effect: the share of its motor's model residual (torque band) that the effect adds, from the same
case recorded again without its effects (same trajectory, controller and noise): 1 - mean(r_clean^2)/mean(r^2).

    .venv/bin/python scripts/bench_diagnose_foreign.py [--cases 30] [--first 0] [--out runs/bench_diagnose_foreign]
        [--rediagnose] [--no-visibility] [--twins]
    .venv/bin/python scripts/bench_diagnose_foreign.py --combine OUT1/bench.json OUT2/bench.json [--write FILE]
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(ROOT))


sys.path.insert(0, str(HERE))
import bench_diagnose as sim_bench  # noqa: E402  (the simulator bench's scoring and report)

URDF = ROOT / "foreign_sim" / "tx40.urdf"


def _same_case(folder: Path, case: dict) -> bool:
    truth = folder / "truth.json"
    if not (truth.is_file() and (folder / "recording.npz").is_file()):
        return False
    try:
        kept = dict(json.loads(truth.read_text()).get("case") or {})
    except (OSError, ValueError):
        return False
    want = json.loads(json.dumps(case))
    kept.setdefault("arm_seed", 0)      # record_case writes the arm it simulated (default 0) into the case
    want.setdefault("arm_seed", 0)
    return kept == want


def record(case: dict, folder: Path) -> Path:
    """The case's recording (``folder/recording.npz``), simulated once (kept when its truth says the same case)."""
    from foreign_sim.record import record_case

    if not _same_case(folder, case):
        folder.mkdir(parents=True, exist_ok=True)
        for old in folder.glob("*.mcap"):       # imports of an earlier recording
            old.unlink()
        record_case(case, folder, progress=False)
    return folder


def import_parts(folder: Path, parts: int) -> list[Path]:
    """js2-import of ``folder/recording.npz`` (no trial labels), as ``parts`` files of one session."""
    from identification import importer as im

    out = [folder / (f"part_{k + 1}.mcap" if parts > 1 else "recording.mcap") for k in range(parts)]
    if all(p.is_file() for p in out):
        return out
    rec = im.load_npz(folder / "recording.npz")          # read once; write_log slices it, never changes it
    edges = np.linspace(0, len(rec.t), parts + 1).astype(int)
    for k, path in enumerate(out):
        if not path.is_file():
            im.write_log(rec, URDF, folder / "drives.yaml", path, robot="tx40",
                         rows=(int(edges[k]), int(edges[k + 1])) if parts > 1 else None)
    return out


def identify(out: Path) -> Path:
    """The model a user would make: the clean identification recording imported and identified (plain command)."""
    from foreign_sim.record import identification_recording
    from identification.cli.identify import main as identify_main

    folder = out / "identification"
    if not (folder / "recording.npz").is_file():
        folder.mkdir(parents=True, exist_ok=True)
        print("bench_diagnose_foreign: simulating the identification recording", file=sys.stderr, flush=True)
        identification_recording(folder)
    log = import_parts(folder, 1)[0]
    model = out / "model"
    if not (model / "model.yaml").is_file():
        print("bench_diagnose_foreign: js2-identify (plain)", file=sys.stderr, flush=True)
        rc = identify_main([str(log), "-o", str(model), "--no-report", "-q"])
        if rc != 0:
            raise SystemExit(f"bench_diagnose_foreign: js2-identify failed ({rc})")
    return model


def identification_figures(model: Path) -> dict:
    """The plain model's held-out figures as model.yaml states them: js2's relative torque error on the held-out
    rows, the OLS baseline's (eq. 1 by ordinary least squares on the same rows) and their ratio."""
    import yaml

    val = yaml.safe_load((model / "model.yaml").read_text())["validation"]
    return {"js2": float(val["relative_error_overall"]), "ols": float(val["baseline"]["relative_error_overall"]),
            "ratio": float(val["baseline"]["ratio_js2_to_baseline"])}


def parts_of(seed: int) -> int:
    """How many files the case's session is split into: 1 (3 cases in 4), else 2-4 (fixed by the seed)."""
    rng = np.random.default_rng(90000 + seed)
    return 1 if rng.uniform() < 0.75 else int(rng.integers(2, 5))


def visibility(model: Path, logs: list[Path], clean_logs: list[Path], effects: list[dict]) -> list[float]:
    """Per effect: 1 - mean(r_clean^2) / mean(r^2) on its motor's residual (torque band, valid rows); a payload
    takes its largest motor."""
    from diagnosis.residual import residual_data
    from js2spec.log import join_logs, read_log
    from js2spec.model import load_model

    mdl = load_model(model)

    def res(paths):
        rd = residual_data(mdl, join_logs([read_log(p) for p in paths]))
        r = np.nan_to_num(rd.lowpass(np.nan_to_num(rd.residual)))
        return r, rd.mask

    r, m = res(logs)
    r0, m0 = res(clean_logs)
    out = []
    for e in effects:
        motors = range(r.shape[1]) if e["kind"] in ("payload_change", "coupling") else [e["joints"][0]]
        gains = []
        for k in motors:
            a = float(np.mean(r[m[:, k], k] ** 2)) if m[:, k].any() else 0.0
            b = float(np.mean(r0[m0[:, k], k] ** 2)) if m0[:, k].any() else 0.0
            gains.append(max(0.0, 1.0 - b / a) if a > 0 else 0.0)
        out.append(max(gains))
    return out


def run_case(seed: int, model: Path, out: Path, rediagnose: bool = False, with_visibility: bool = True) -> dict:
    from foreign_sim.cases import draw_case

    case = draw_case(seed)
    res_path = out / f"case_{seed:03d}.json"
    if res_path.is_file() and not rediagnose:
        row = json.loads(res_path.read_text())
        if row.get("case") == json.loads(json.dumps(case)):
            return row
    folder = out / "cases" / f"{seed:03d}"
    t0 = time.time()
    record(case, folder)
    parts = parts_of(seed)
    logs = import_parts(folder, parts)
    vis = None
    if with_visibility and case["effects"]:
        clean = dict(case, effects=[])
        cfolder = record(clean, out / "cases" / f"{seed:03d}_clean")
        vis = visibility(model, logs, import_parts(cfolder, parts), case["effects"])
    row = _diagnosed(model, logs, case, effects=case["effects"], visibility=vis, sim_s=round(time.time() - t0, 1))
    res_path.write_text(json.dumps(row, default=float))
    return row


def _diagnosed(model: Path, logs: list[Path], case: dict, **fields) -> dict:
    """The row of one diagnosis (the plain defaults) of ``logs``, one session: what was named, where structure is
    left unexplained, the time it took, and ``fields`` (effects, visibility, ...)."""
    from diagnosis.run import diagnose

    t1 = time.time()
    result = diagnose(model, logs if len(logs) > 1 else logs[0])
    named = [{"kind": f["kind"], "joint": int(f["effect"]["joints"][0]), "effect": f["effect"],
              "report_gain": f["holdout_gain"], **sim_bench._alike(f)} for f in result.findings()]
    return {"seed": case["seed"], "case": case, "cycle_hz": float(case["rate_hz"]), "files": len(logs),
            "controller": case.get("controller"), "named": named,
            "unexplained": [u["joint_index"] for u in result.unexplained()], **fields,
            "diagnose_s": round(time.time() - t1, 1)}


def run_twin(seed: int, model: Path, out: Path, rediagnose: bool = False) -> dict | None:
    """The case's effect-free twin (the visibility's recording: same arm, trajectory, controller, rate, noise and
    file split) diagnosed as a clean case: a row with no effects, or None when the twin was never recorded (a clean
    case has none; ``--no-visibility`` makes none)."""
    from foreign_sim.cases import draw_case

    case = draw_case(seed)
    folder = out / "cases" / f"{seed:03d}_clean"
    if not case["effects"] or not _same_case(folder, dict(case, effects=[])):
        return None
    res_path = out / f"twin_{seed:03d}.json"
    if res_path.is_file() and not rediagnose:
        row = json.loads(res_path.read_text())
        if row.get("case") == json.loads(json.dumps(case)):
            return row
    row = _diagnosed(model, import_parts(folder, parts_of(seed)), case, twin_of=seed, effects=[], visibility=None,
                     sim_s=None)
    res_path.write_text(json.dumps(row, default=float))
    return row


def _clean_names(score: dict) -> str:
    """What the clean recordings of a score got named, per kind (its confusion matrix's ``none`` row)."""
    named = {k: v for k, v in score["confusion"]["none"].items() if k != "nothing" and v}
    return ", ".join(f"{k} {v}" for k, v in named.items()) or "none"


def combine(paths: list[Path], write: Path | None = None, seeds: range | None = None) -> int:
    """Score several runs' bench.json together (e.g. seeds 0-19 and 20-39 run in two processes); ``seeds``: only
    those cases and their twins (a set cut out of runs that were split otherwise)."""
    rows, twins, ident = [], [], None
    for p in paths:
        try:
            d = json.loads(p.read_text())
        except (OSError, ValueError) as exc:
            print(f"bench_diagnose_foreign: error: {p}: {exc}", file=sys.stderr)
            return 2
        rows += d["rows"]
        twins += d.get("twins", [])
        ident = d.get("identification") or ident
    if seeds is not None:
        rows = [r for r in rows if r["seed"] in seeds]
        twins = [r for r in twins if r["seed"] in seeds]
    if not rows:
        print("bench_diagnose_foreign: error: no cases to combine" + (f" in seeds {seeds.start}-{seeds.stop - 1}"
                                                                     if seeds is not None else ""), file=sys.stderr)
        return 2
    rows.sort(key=lambda r: r["seed"])
    twins.sort(key=lambda r: r["seed"])
    s = sim_bench.score(rows)
    print(f"seeds {rows[0]['seed']}-{rows[-1]['seed']} ({len(rows)} cases)")
    sim_bench.print_report(s, rows)
    t = sim_bench.score(twins) if twins else None
    if t is not None:
        print(f"clean twins: {t['clean_none']}/{t['clean']} named nothing; names on them: " + _clean_names(t))
    clean = (s["clean_none"] + (t["clean_none"] if t else 0), s["clean"] + (t["clean"] if t else 0))
    print(f"clean recordings (clean cases and twins): {clean[0]}/{clean[1]} named nothing")
    if write is not None:
        write.write_text(json.dumps({"score": s, "rows": rows, "twins": twins, "twin_score": t,
                                     "identification": ident}, default=float))
    return 0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cases", type=int, default=30, help="number of cases (seeds FIRST .. FIRST+CASES-1)")
    ap.add_argument("--first", type=int, default=0, help="first seed")
    ap.add_argument("--out", type=Path, default=Path("runs/bench_diagnose_foreign"),
                    help="work folder: recordings, model, one JSON per case, bench.json")
    ap.add_argument("--rediagnose", action="store_true", help="diagnose again (after a change to the diagnosis)")
    ap.add_argument("--no-visibility", action="store_true",
                    help="skip each case's effect-free twin recording (no visibility column)")
    ap.add_argument("--twins", action="store_true",
                    help="also diagnose each effect case's effect-free twin as a clean case (bench.json 'twins')")
    ap.add_argument("--combine", type=Path, nargs="+", metavar="BENCH_JSON",
                    help="print the score of these runs' bench.json together (rows and twins; no diagnosis) and, "
                         "with --write FILE, write them as one file")
    ap.add_argument("--write", type=Path, help="with --combine: the combined file to write")
    ap.add_argument("--seeds", metavar="FIRST-LAST",
                    help="with --combine: only these cases and their twins (e.g. 40-79)")
    a = ap.parse_args(argv)
    if a.combine:
        seeds = None
        if a.seeds:
            try:
                lo, hi = (int(x) for x in a.seeds.split("-"))
            except ValueError:
                ap.error(f"--seeds {a.seeds!r}: give FIRST-LAST, e.g. 40-79")
            seeds = range(lo, hi + 1)
        return combine(a.combine, a.write, seeds)
    a.out.mkdir(parents=True, exist_ok=True)
    model = identify(a.out)
    ident = identification_figures(model)
    print(f"js2-identify on the clean identification recording (90 s, 500 Hz): held-out relative torque error "
          f"{ident['js2']:.2%}, the OLS baseline's {ident['ols']:.2%} (ratio {ident['ratio']:.4f})", flush=True)
    rows = []
    for seed in range(a.first, a.first + a.cases):
        row = run_case(seed, model, a.out, rediagnose=a.rediagnose, with_visibility=not a.no_visibility)
        rows.append(row)
        got = ", ".join(f"{f['kind']} j{f['joint']}" for f in row["named"]) or "nothing"
        want = ", ".join(f"{e['kind']} j{e['joints'][0]}" for e in row["effects"]) or "nothing"
        vis = " ".join(f"{v:.2f}" for v in row["visibility"] or [])
        print(f"case {seed:3d} {row['cycle_hz']:.0f} Hz x{row['files']}: concealed {want} (vis {vis or '-'}); "
              f"named {got} ({row['diagnose_s']} s)", file=sys.stderr, flush=True)
    s = sim_bench.score(rows)
    sim_bench.print_report(s, rows)
    twins = []
    if a.twins:
        for seed in range(a.first, a.first + a.cases):
            row = run_twin(seed, model, a.out, rediagnose=a.rediagnose)
            if row is None:
                continue
            twins.append(row)
            got = ", ".join(f"{f['kind']} j{f['joint']}" for f in row["named"]) or "nothing"
            print(f"twin {seed:3d} {row['cycle_hz']:.0f} Hz x{row['files']} (clean): named {got} "
                  f"({row['diagnose_s']} s)", file=sys.stderr, flush=True)
        t = sim_bench.score(twins)
        print(f"clean twins (each effect case recorded again without its effects): {t['clean_none']}/{t['clean']} "
              f"named nothing; names on them: " + _clean_names(t))
    (a.out / "bench.json").write_text(json.dumps({"score": s, "rows": rows, "twins": twins, "identification": ident},
                                                 default=float))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
