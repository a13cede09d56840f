#!/usr/bin/env python3
"""Clean real recordings under conditions the other benches do not use: does js2-diagnose stay quiet?

The issue's rule is that a clean real recording gets ``none`` or ``unexplained``, never a named effect. The real-data
bench (bench_diagnose_real.py) and prove_diagnosis_real.py check it on the three whole KUKA LWR4+ recordings with
one model, the plain ``js2-identify kuka_1.mcap``. A user has other models and other stretches of recording; this
bench asks the same question, with the plain commands, on:

1. **models**: every KUKA recording diagnosed with the model the plain ``js2-identify`` makes from each of the three
   (9 pairs; the diagonal is a model's own recording);
2. **windows**: 60 % of each recording (0-60 %, 20-80 %, 40-100 %: 15 s of 25 s) at 200 Hz and decimated to 100 Hz,
   with the kuka_1 model (18 windows; kuka_1's are that model's own data);
3. **a second arm**: the Staubli TX40 recording (5 kHz, motor currents, 9 s) with the model identified from it;
4. **the payload protocol across models** (not clean: prove_diagnosis_real.py's 2 kg on the hand added to each
   recording along its motion), each diagnosed with each of the three models: is the payload found whatever the
   model (``payload_rows`` in bench.json, apart from the clean rows).

Nothing is added to the recordings of 1-3: whatever is named there is named on a clean recording (a false name, as
the issue counts it, though a real arm between two sessions does change: a torque sensor's zero, its friction).
Prints one row per condition (what was named, what was reported unexplained), the count of conditions with a name
and the payload's line; writes OUT/bench.json.

    .venv/bin/python scripts/bench_diagnose_real_clean.py [--data ../shared/data/real] [--out runs/bench_real_clean]
    .venv/bin/python scripts/bench_diagnose_real_clean.py \
        --from-json docs/bench/diagnose-real-clean-2026-11-27-stop32.json
"""
from __future__ import annotations

import argparse
import contextlib
import importlib.util
import io
import json
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))

WINDOWS = ((0.0, 0.6), (0.2, 0.8), (0.4, 1.0))     # shares of a KUKA recording's length
RATES = (1, 2)                                      # decimation: 200 Hz, 100 Hz


def _script(name: str):
    spec = importlib.util.spec_from_file_location(name, HERE / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


prove = _script("prove_diagnosis_real")      # import, identify, the payload's torque, the plain js2-diagnose


def window_name(which: int, decimate: int, part) -> str:
    return f"kuka_{which} {200 // decimate} Hz {int(part[0] * 100)}-{int(part[1] * 100)} %"


def conditions(data: Path, out: Path, progress=print) -> list[dict]:
    """(name, group, model, log) of every condition, the recordings imported and the models identified as needed."""
    from identification.examples.real_arms import import_tx40, load_kuka, write_kuka

    logs = prove.import_logs(data, out)
    models = {}
    for i, log in enumerate(logs, start=1):
        if not (out / f"model_kuka_{i}" / "model.yaml").is_file():
            progress(f"identifying a model from kuka_{i} (the plain js2-identify) ...")
        models[i] = prove.identify(log, out / f"model_kuka_{i}")
    rows = [{"name": f"kuka_{k} with the kuka_{i} model", "group": "models", "model": models[i], "log": logs[k - 1],
             "own": i == k} for i in (1, 2, 3) for k in (1, 2, 3)]
    for k in (1, 2, 3):
        for dec in RATES:
            for part in WINDOWS:
                path = out / "windows" / f"kuka_{k}_d{dec}_{int(part[0] * 100)}-{int(part[1] * 100)}.mcap"
                if not path.is_file():
                    path.parent.mkdir(parents=True, exist_ok=True)
                    write_kuka(load_kuka(data, k)[0], data, path, decimate=dec, part=part)
                rows.append({"name": window_name(k, dec, part) + " with the kuka_1 model", "group": "windows",
                             "model": models[1], "log": path, "own": k == 1})
    tx = out / "tx40.mcap"
    if not tx.is_file():
        import_tx40(data, tx)
    if not (out / "model_tx40" / "model.yaml").is_file():
        progress("identifying a model from the TX40 recording ...")
    tx_model = prove.identify(tx, out / "model_tx40")
    rows.append({"name": "tx40 with its own model", "group": "second arm", "model": tx_model, "log": tx, "own": True})
    return rows


def run(data: Path, out: Path) -> list[dict]:
    out.mkdir(parents=True, exist_ok=True)
    results = []
    conds = conditions(data, out)
    for n, c in enumerate(conds, start=1):
        t0 = time.perf_counter()
        with contextlib.redirect_stdout(io.StringIO()):       # the CLI's own summary: the row below says it
            d = prove.diagnose_cli(c["model"], c["log"], out / "diag" / f"{n:02d}")
        row = {"name": c["name"], "group": c["group"], "own_recording": c["own"],
               "named": [{"kind": f["kind"], "joint": f["joint"], "effect": f["effect"], "summary": f["summary"],
                          "report_gain": f.get("holdout_gain")} for f in d["findings"]],
               "unexplained": [u["joint"] for u in d["unexplained"]], "verdict": d["verdict"].split(":")[0],
               "seconds": round(time.perf_counter() - t0, 1)}
        results.append(row)
        print(f"[{n}/{len(conds)}] {line(row)}", flush=True)
    return results


def payload_across_models(data: Path, out: Path) -> list[dict]:
    """Step 4: kuka_k + the protocol's 2 kg on the hand, diagnosed with the kuka_m model, every k and m."""
    rows = []
    for k in (1, 2, 3):
        log = out / "payload" / f"kuka_{k}_2kg.mcap"
        if not log.is_file():
            log.parent.mkdir(parents=True, exist_ok=True)
            prove.payload_log(data, log, which=k)
        for m in (1, 2, 3):
            with contextlib.redirect_stdout(io.StringIO()):
                d = prove.diagnose_cli(out / f"model_kuka_{m}", log, out / "diag" / f"payload_{k}{m}")
            named = [{"kind": f["kind"], "joint": f["joint"], "effect": f["effect"]} for f in d["findings"]]
            rows.append({"name": f"kuka_{k} + {prove.PAYLOAD_MASS:g} kg with the kuka_{m} model",
                         "own_recording": k == m, "named": named})
            print(f"{rows[-1]['name']}: " + ", ".join(
                f"{f['kind']} on {f['joint']}" + (f" {f['effect']['mass']:.3f} kg" if "mass" in f["effect"] else "")
                for f in named), flush=True)
    return rows


def payload_summary(rows: list[dict]) -> str:
    """The payload across models in one line: found on the hand or the link before it, mass range, other names."""
    masses = [f["effect"]["mass"] for r in rows for f in r["named"] if f["kind"] == "payload_change"]
    hand = sum(any(f["kind"] == "payload_change" and f["joint"] == "lwr_6_joint" for f in r["named"]) for r in rows)
    others = sum(sum(f["kind"] != "payload_change" for f in r["named"]) for r in rows)
    return (f"payload across models: found in {len(masses)} of {len(rows)} (on the hand in {hand}), "
            f"{min(masses):.3f}-{max(masses):.3f} kg for 2 kg; {others} other names beside it")


def line(row: dict) -> str:
    named = ", ".join(f"{f['kind']} on {f['joint']}" for f in row["named"]) or "nothing"
    return f"{row['name']}: named {named}; unexplained on {len(row['unexplained'])} joint(s)"


def summary(rows: list[dict]) -> dict:
    """Per group: conditions, conditions with a named effect; and over all of them."""
    out = {}
    for g in ("models", "windows", "second arm"):
        sub = [r for r in rows if r["group"] == g]
        out[g] = {"conditions": len(sub), "named": sum(bool(r["named"]) for r in sub),
                  "named_other_recording": sum(bool(r["named"]) for r in sub if not r["own_recording"]),
                  "other_recording": sum(not r["own_recording"] for r in sub)}
    out["all"] = {"conditions": len(rows), "named": sum(bool(r["named"]) for r in rows)}
    return out


def report(rows: list[dict]) -> str:
    s = summary(rows)
    text = [line(r) for r in rows]
    text.append("")
    for g in ("models", "windows", "second arm"):
        x = s[g]
        text.append(f"{g}: {x['named']} of {x['conditions']} clean conditions name an effect "
                    f"({x['named_other_recording']} of the {x['other_recording']} not on the model's own recording)")
    text.append(f"all: {s['all']['named']} of {s['all']['conditions']} clean conditions name an effect")
    return "\n".join(text)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__)
    p.add_argument("--data", type=Path, default=prove.DEFAULT_DATA, help="the real recordings (default %(default)s)")
    p.add_argument("--out", type=Path, default=Path("runs/bench_real_clean"))
    p.add_argument("--from-json", type=Path, help="print the report of a saved bench.json")
    a = p.parse_args(argv)
    if a.from_json:
        try:
            saved = json.loads(a.from_json.read_text())
            rows = saved["rows"]
        except (OSError, ValueError, KeyError) as e:
            print(f"bench_diagnose_real_clean: cannot read {a.from_json}: {e}", file=sys.stderr)
            return 2
        print(report(rows))
        pay = saved.get("payload_rows")
        if pay:
            print(payload_summary(pay))
        return 0
    if not (a.data / "kuka_lwr4").is_dir() or not (a.data / "staubli_tx40").is_dir():
        print(f"bench_diagnose_real_clean: the real recordings are not at {a.data} (kuka_lwr4/, staubli_tx40/): "
              "give --data", file=sys.stderr)
        return 2
    rows = run(a.data, a.out)
    pay = payload_across_models(a.data, a.out)
    (a.out / "bench.json").write_text(json.dumps({"rows": rows, "summary": summary(rows), "payload_rows": pay},
                                                 indent=1))
    print()
    print(report(rows))
    print(payload_summary(pay))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
