#!/usr/bin/env python3
"""Every candidate reading of every ladder step of js2-diagnose, for recordings of a bench: what a change to one
term's rule would touch, read before the change is made.

``diagnosis.json`` keeps the first step's candidates (``candidates_step1``); a rule changed on one term changes the
diagnosis only where one of that term's readings, at some step, falls in the window the change moves. So: diagnose
each recording with the model (the plain defaults, ``diagnosis.run.diagnose``), and write OUT/STEM.json with the
findings, the references and, for each step, every candidate scored there (term class, kind, joint, grid point,
coefficients and their std, the gains: own motor, select, over all motors, capped, fit, report; plausible, why not,
why the ladder did not take it, the effect). Stop 37 read its rule changes on these dumps of the 380 simulator and
180 real-bench cases (docs/diagnosis.md, stop 37). A recording whose dump exists is skipped.

    .venv/bin/python scripts/diagnose_rankings.py MODEL_DIR OUT REC.mcap [REC.mcap ...]
    e.g.  scripts/diagnose_rankings.py runs/bench_diagnose/model runs/rankings runs/bench_diagnose/runs/case_0*.mcap
"""
from __future__ import annotations

import argparse
import contextlib
import io
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from diagnosis.report import _jsonable  # noqa: E402  (numpy to JSON's types, NaN as null: diagnosis.json's)


def reading(s) -> dict:
    """One scored candidate (``search.Scored``) as a row."""
    f = s.fitted
    return {"term": type(s.term).__name__, "kind": f.kind, "joint": f.joint, "hyper": _jsonable(f.hyper),
            "coef": _jsonable(f.coef), "std": _jsonable(f.coef_std), "own": s.select_gain_own, "sel": s.select_gain,
            "all": s.select_gain_all, "cap": s.select_gain_capped, "fit": s.fit_gain, "hold": s.holdout_gain,
            "ok": bool(f.plausible), "why": f.why_not, "rej": s.rejected, "effect": _jsonable(f.effect)}


def rankings(model: Path, recording: Path) -> dict:
    """The diagnosis of one recording as findings, references and every step's candidates."""
    from diagnosis.run import diagnose

    with contextlib.redirect_stdout(io.StringIO()):
        d = diagnose(model, recording)
    s = d.search
    return _jsonable({"recording": str(recording), "verdict": d.verdict(),
                   "accepted": [reading(a) for a in s.accepted_], "references": [reading(a) for a in s.references_],
                   "rankings": [[reading(x) for x in rank] for rank in s.rankings_]})


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("model", type=Path, help="the model folder (model.yaml) to diagnose with")
    ap.add_argument("out", type=Path, help="folder for the dumps (OUT/STEM.json, one per recording)")
    ap.add_argument("recordings", type=Path, nargs="+", help="recordings (.mcap), each diagnosed on its own")
    a = ap.parse_args(argv)
    if not (a.model / "model.yaml").is_file():
        print(f"diagnose_rankings: error: {a.model / 'model.yaml'}: not found; pass a model folder made by "
              "js2-identify", file=sys.stderr)
        return 2
    missing = [str(p) for p in a.recordings if not p.is_file()]
    if missing:
        print(f"diagnose_rankings: error: not found: {', '.join(missing)}", file=sys.stderr)
        return 2
    from js2spec.errors import Js2Error

    a.out.mkdir(parents=True, exist_ok=True)
    failed = 0
    for k, rec in enumerate(a.recordings, 1):
        path = a.out / f"{rec.stem}.json"
        if path.is_file():
            continue
        try:
            dump = rankings(a.model, rec)
        except Js2Error as exc:          # a recording (or model) js2 cannot read: said, and the others go on
            print(f"diagnose_rankings: error: {exc}", file=sys.stderr, flush=True)
            failed += 1
            continue
        path.write_text(json.dumps(dump))
        print(f"[{k}/{len(a.recordings)}] {rec.name} -> {path}", file=sys.stderr, flush=True)
    return 2 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
