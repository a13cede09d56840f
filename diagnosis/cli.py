"""``js2-diagnose``: find the physics a model leaves out, from a recording it does not fit well."""
from __future__ import annotations

import argparse
import sys

from js2spec.errors import Js2Error

from .library import KINDS

EPILOG = """\
examples:
  js2-diagnose runs/model/model.yaml runs/recording.mcap -o runs/diagnosis
  js2-diagnose runs/model runs/recording.mcap -o out --kinds stribeck cogging --min-gain 0.2
  js2-diagnose runs/model part1.mcap part2.mcap part3.mcap -o out    (one session recorded over three files)

what it does:
  1. predicts the recording's motor torques with the model (eq. 1, the identified URDF + model.yaml friction,
     motor inertias and offsets), filtered as the model was identified (model.yaml `filters`, default 50 Hz
     velocity, 7 Hz acceleration and torque), every cut-off kept below 0.4 x the sample rate; joint-side torques
     (torque sensors) are carried to the motor side with K^T;
  2. splits the recording in three: FIT = the trials other than 'validation' ('excitation' when present); SELECT
     and REPORT = 1/3 and 2/3 of the 'validation' trial's interleaved time blocks (a second trajectory). Without a
     'validation' trial (or when it is the only one): REPORT = the last 30 %% of the recording, the rest in
     interleaved time blocks, 2/3 FIT, 1/3 SELECT;
  3. fits every candidate term (named effects: %s; each on every joint/link) on FIT, ranks them on SELECT and
     walks down the ranking to the first that cuts the SELECT residual of its motors by --min-gain (its FIT
     residual by --min-fit-gain) and beats the null of a plain refit of the model's own friction; accepts it,
     ranks again, until none passes (at most
     --max-terms); structure only the refit explains is reported 'unexplained', never named (so is a constant
     torque offset on a recording the model was identified from: the model's own choice, js2-identify --offsets);
  4. reports the gains on REPORT alone, which the search never saw;
  5. with --replay: replays the recorded motion through the simulator (hil_sim, inverse dynamics) with the model,
     then with the model plus the found effects, and compares the simulated torques with the recording on REPORT.

writes OUTDIR/diagnosis.json, OUTDIR/report.html, OUTDIR/model_diagnosed.yaml (the model plus `unmodelled:`),
OUTDIR/effects.yaml (the found effects in hil_sim's format, to simulate them). Exit code 0; 1 with --strict when
something was found (the model is incomplete); 2 on bad input.
""" % ", ".join(KINDS)


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="js2-diagnose", formatter_class=argparse.RawDescriptionHelpFormatter,
                                description="Locate and name the physics an identified model leaves out, model it, "
                                            "and show the fit improve on held-out data.", epilog=EPILOG)
    p.add_argument("model", help="model.yaml written by js2-identify (or its folder)")
    p.add_argument("recordings", nargs="+", metavar="LOG",
                   help="js2 log(s) (MCAP) of the same arm, ideally with 'excitation' and 'validation' trials; "
                        "several files are one session recorded in parts, joined in the order given")
    p.add_argument("-o", "--outdir", required=True, help="folder for the outputs (created)")
    p.add_argument("--holdout-trial", default="validation", help="trial held out for scoring (default: validation)")
    p.add_argument("--fit-trial", action="append", dest="fit_trials", metavar="TRIAL",
                   help="trial(s) to fit the candidate terms on (repeatable; default: excitation, else the rest)")
    p.add_argument("--kinds", nargs="+", choices=KINDS, metavar="KIND",
                   help=f"candidate kinds to try (default: all: {', '.join(KINDS)})")
    p.add_argument("--min-gain", type=float, default=0.12,
                   help="select residual reduction a term must reach on its motors (default 0.12)")
    p.add_argument("--min-fit-gain", type=float, default=None,
                   help="fit residual reduction a named term must reach on its motors, on the rows it was fitted "
                        "to (default 0.18, or --min-gain when that is higher; what is reported 'unexplained' keeps "
                        "--min-gain)")
    p.add_argument("--max-terms", type=int, default=4, help="most terms to accept (default 4)")
    p.add_argument("--min-speed", type=float, default=0.01,
                   help="rad/s at the JOINT (so any gear ratio): slower samples of a joint are left out, friction "
                        "being undefined at rest (default 0.01; motor i uses min-speed / max_j |K_ji|)")
    p.add_argument("--payload-removed", action="store_true",
                   help="a mass may have been taken off the arm since the model was identified (a tool removed): "
                        "payload_change may then read a negative mass (default: only a mass added is named)")
    p.add_argument("--replay", action="store_true",
                   help="also replay the recorded motion through the simulator (hil_sim) with the model, then with "
                        "the model plus the found effects, and compare with the recording on the report rows "
                        "(diagnosis.json 'replay', a report section)")
    p.add_argument("--strict", action="store_true", help="exit 1 when the model is found incomplete")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bars")
    return p


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    from .report import gain_scope, unconfirmed, write_outputs
    from .run import DiagnoseOptions, diagnose

    if not 0 < args.min_gain < 1:
        print("js2-diagnose: error: --min-gain must lie between 0 and 1", file=sys.stderr)
        return 2
    if args.min_fit_gain is not None and not 0 < args.min_fit_gain < 1:
        print("js2-diagnose: error: --min-fit-gain must lie between 0 and 1", file=sys.stderr)
        return 2
    opt = DiagnoseOptions(holdout_trial=args.holdout_trial, fit_trials=args.fit_trials, kinds=args.kinds,
                          min_gain=args.min_gain, min_fit_gain=args.min_fit_gain, max_terms=args.max_terms,
                          min_speed=args.min_speed, payload_removed=args.payload_removed,
                          progress=not args.quiet and sys.stderr.isatty())
    try:
        from js2spec.files import check_output_folder
        check_output_folder(args.outdir)
        res = diagnose(args.model, args.recordings, opt)
        paths = write_outputs(res, args.outdir, replay=args.replay)
    except Js2Error as exc:
        from js2spec.log import damage_notes
        notes = damage_notes(args.recordings)
        why = f" (note: {'; '.join(notes)}: what is missing may have been in the lost part)" if notes else ""
        print(f"js2-diagnose: error: {exc}{why}", file=sys.stderr)
        return 2
    except OSError as exc:
        print(f"js2-diagnose: error: cannot write {exc.filename or args.outdir}: {exc.strerror or exc}; choose "
              f"another -o", file=sys.stderr)
        return 2
    d = res.to_dict()
    for n in d["notes"]:
        print(f"note: {n}")
    print(f"split: {d['split']}")
    print(f"where: {d['location']['text']}")
    print(f"verdict: {d['verdict']}")
    for f in d["findings"]:
        print(f"  {f['kind']:<24} {f['joint']:<12} report gain {f['holdout_gain']:6.1%}   effect: "
              f"{ {k: v for k, v in f['effect'].items() if k != 'kind'} }")
    for u in d["unexplained"]:
        print(f"  unexplained              {u['joint']:<12} {u['fraction_of_residual']:.0%} of its select residual, "
              f"largest {u['regime']}, mostly {u['frequency_band']} (what takes it: {u['reference']})")
    print(f"report gain of {gain_scope(d)} together (rows the search never saw): {d['holdout_gain']:.1%}")
    for f in unconfirmed(d):
        print(f"not confirmed on the report rows: {f['kind']} on {f['joint']} (its report gain "
              f"{f['holdout_gain']:.1%}): a lead to check on another recording, not a finding to act on")
    if args.replay:
        import json

        rep = json.loads(paths["json"].read_text())["replay"]
        print("replay through hil_sim, RMS recording - simulation on the report rows (N*m), model -> model + "
              "effects: " + ", ".join(f"motor {i + 1} {b:.3g} -> {a:.3g}" for i, (b, a) in
                                      enumerate(zip(rep["rms_model"], rep["rms_model_effects"]))
                                      if b is not None and a is not None)
              + (f"; gain {rep['gain']:.1%}" if rep["gain"] is not None else ""))
        fw = rep["forward"]
        pairs = zip(fw["model"]["position_rms"], fw["model_effects"]["position_rms"])
        print("forward replay (recorded torque + 5 Hz tracking), RMS joint angle gap on the report rows (rad), model "
              "-> model + effects: " + ", ".join(f"joint {i + 1} {b:.3g} -> {a:.3g}" for i, (b, a) in enumerate(pairs)
                                                 if b is not None and a is not None))
    print(f"-> {paths['report']}, {paths['model'].name}, {paths['effects'].name}, {paths['json'].name}")
    return 1 if (args.strict and d["findings"]) else 0


if __name__ == "__main__":
    raise SystemExit(main())
