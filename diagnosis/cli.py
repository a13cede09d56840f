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

what it does:
  1. predicts the recording's motor torques with the model (eq. 1, the identified URDF + model.yaml friction and
     motor inertias), filtered as identification filters (50 Hz velocity, 7 Hz acceleration and torque);
  2. fits every candidate term (one per effect kind: %s) on the fit part of the recording (default: the
     'excitation' trial, else every trial but the held-out one, else the first 2/3) and scores it on the
     held-out part (default: the 'validation' trial, else the last 1/3);
  3. accepts the best term while it cuts the held-out residual of its motors by at least --min-gain, then looks
     again (at most --max-terms terms).

writes OUTDIR/diagnosis.json, OUTDIR/report.html, OUTDIR/model_diagnosed.yaml (the model plus `unmodelled:`),
OUTDIR/effects.yaml (the found effects in hil_sim's format, to simulate them). Exit code 0; 1 with --strict when
something was found (the model is incomplete); 2 on bad input.
""" % ", ".join(KINDS)


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="js2-diagnose", formatter_class=argparse.RawDescriptionHelpFormatter,
                                description="Locate and name the physics an identified model leaves out, model it, "
                                            "and show the fit improve on held-out data.", epilog=EPILOG)
    p.add_argument("model", help="model.yaml written by js2-identify (or its folder)")
    p.add_argument("recording", help="a js2 log (MCAP) of the same arm, ideally with 'excitation' and "
                                     "'validation' trials")
    p.add_argument("-o", "--outdir", required=True, help="folder for the outputs (created)")
    p.add_argument("--holdout-trial", default="validation", help="trial held out for scoring (default: validation)")
    p.add_argument("--fit-trial", action="append", dest="fit_trials", metavar="TRIAL",
                   help="trial(s) to fit the candidate terms on (repeatable; default: excitation, else the rest)")
    p.add_argument("--kinds", nargs="+", choices=KINDS, metavar="KIND",
                   help=f"candidate kinds to try (default: all: {', '.join(KINDS)})")
    p.add_argument("--min-gain", type=float, default=0.12,
                   help="held-out (and fit) residual reduction a term must reach on its motors (default 0.12)")
    p.add_argument("--max-terms", type=int, default=3, help="most terms to accept (default 3)")
    p.add_argument("--min-speed", type=float, default=1.0,
                   help="rad/s at the motor: slower samples are left out, friction being undefined at rest "
                        "(default 1.0)")
    p.add_argument("--strict", action="store_true", help="exit 1 when the model is found incomplete")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bars")
    return p


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    from .report import write_outputs
    from .run import DiagnoseOptions, diagnose

    if not 0 < args.min_gain < 1:
        print("js2-diagnose: error: --min-gain must lie between 0 and 1", file=sys.stderr)
        return 2
    opt = DiagnoseOptions(holdout_trial=args.holdout_trial, fit_trials=args.fit_trials, kinds=args.kinds,
                          min_gain=args.min_gain, max_terms=args.max_terms, min_speed=args.min_speed,
                          progress=not args.quiet and sys.stderr.isatty())
    try:
        res = diagnose(args.model, args.recording, opt)
        paths = write_outputs(res, args.outdir)
    except Js2Error as exc:
        print(f"js2-diagnose: error: {exc}", file=sys.stderr)
        return 2
    d = res.to_dict()
    for n in d["notes"]:
        print(f"note: {n}")
    print(f"split: {d['split']}")
    print(f"where: {d['location']['text']}")
    print(f"verdict: {d['verdict']}")
    for f in d["findings"]:
        i = f["joint_index"]
        print(f"  {f['kind']:<24} {f['joint']:<6} held-out gain {f['holdout_gain']:6.1%}   effect: "
              f"{ {k: v for k, v in f['effect'].items() if k != 'kind'} }")
    print(f"held-out gain of the found terms together: {d['holdout_gain']:.1%}")
    print(f"-> {paths['report']}, {paths['model'].name}, {paths['effects'].name}, {paths['json'].name}")
    return 1 if (args.strict and d["findings"]) else 0


if __name__ == "__main__":
    raise SystemExit(main())
