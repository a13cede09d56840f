"""``js2-identify LOG... -o OUTDIR``: the dynamic model of an arm from its js2 logs (thin CLI over the pipeline)."""
from __future__ import annotations

import os

# Single-threaded BLAS: the matrices here are small (~50 parameters) and OpenBLAS's spinning worker threads make a
# loaded 2-core machine several times slower. Set before numpy is first imported; a user's own setting wins.
for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")
import argparse
import sys
from pathlib import Path

DESCRIPTION = """\
Identify the dynamic model of a manipulator (eq. 1 of Sakamoto et al., motor side) from js2 logs.

Give it the log(s) of one session, e.g. from `js2-acquire --trial all -o run.mcap`, holding:
  static        breakaway torque ramps per axis      -> static friction f_s and gravity (eq. 2-4)
  velocity      constant speeds per axis             -> viscous B and Coulomb f_c (eq. 5, Fig. 2)
  acceleration  all axes accelerating together       -> inertial parameters and motor inertias by RLS
  validation    a different motion                   -> held-out check of the model
The "mixed" method (the paper's) fixes friction from the sequential tests and fits the rest; it is chosen
when the logs hold them. Otherwise "simultaneous" fits everything from the acceleration (or imported
'excitation') trial. Filter cut-offs follow the sample rate (the paper's 50/7 Hz where the rate allows).
Each automatic choice is one line of the summary. The summary also prints the held-out error of a
textbook OLS fit on the same samples, to show what js2 adds.

Writes into OUTDIR:
  model.yaml              all parameters with standard errors, method, sha256 of every input
  robot_identified.urdf   the URDF with identified (physically consistent) link inertials
  report.html             Fig. 2, Fig. 3, validation plots and tables (open in a browser)
  verdict.json            pass/fail against thresholds (condition number, validation NRMS, ...)

Exit codes: 0 done (and verdict passed, with --strict), 1 verdict failed with --strict,
2 bad input (message names the file and the problem).
"""

EPILOG = """\
examples:
  js2-identify run.mcap -o model/
  js2-identify static.mcap velocity.mcap accel.mcap --validate valid.mcap -o model/ --strict
  js2-identify imported.mcap -o tx40/      # an imported recording: simultaneous method, chosen filters
"""


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="js2-identify", description=DESCRIPTION, epilog=EPILOG,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("logs", nargs="+", metavar="LOG", help="js2 log files (.mcap) of one session")
    p.add_argument("-o", "--outdir", required=True, help="output folder (created if needed)")
    p.add_argument("--method", choices=["auto", "mixed", "simultaneous"], default="auto",
                   help="which estimate becomes the model (default auto: mixed when the logs hold static and velocity "
                        "trials, else simultaneous; both are always computed when possible)")
    p.add_argument("--validate", nargs="*", default=[], metavar="LOG",
                   help="extra log(s) used only for validation")
    p.add_argument("--fit-trials", default=None,
                   help="comma-separated trial names whose data fit the inertial parameters (default: acceleration "
                        "if present, else excitation, else 'all' = every sample)")
    p.add_argument("--validation-trials", default="validation",
                   help="comma-separated trial names held out for validation (default: validation); without any, "
                        "the last --holdout of the fitting data is held out")
    p.add_argument("--holdout", type=float, default=0.25, help="held-out fraction when there is no validation data")
    p.add_argument("--fc-velocity", type=float, default=None,
                   help="velocity filter cut-off, Hz (default: the paper's 50 where the sample rate allows, else "
                        "0.8 x Nyquist)")
    p.add_argument("--fc-acceleration", type=float, default=None,
                   help="acceleration and torque filter cut-off, Hz (default: the paper's 7, raised to 2 x the "
                        "motion bandwidth for fast motions, below the velocity cut-off)")
    p.add_argument("--iterations", type=int, default=35000,
                   help="RLS iterations (samples), 0 = all (paper: about 35,000)")
    p.add_argument("--offsets", action=argparse.BooleanOptionalAction, default=None,
                   help="a constant torque offset per axis (sensor or current bias) in the model (default: tried by "
                        "the simultaneous method and kept if cross-validation on the fit data prefers it)")
    p.add_argument("--sqrt-viscous", action=argparse.BooleanOptionalAction, default=None,
                   help="a friction term Bs sgn(v) sqrt|v| per axis (default: tried by the simultaneous method and "
                        "kept if cross-validation on the fit data prefers it)")
    p.add_argument("--fig3", default="J_4z,B_4,fc_4",
                   help="parameters plotted in Fig. 3 (paper's J_<i>z, or standard names such as Ja_2, B_4, fc_4, "
                        "Ixx_link4)")
    p.add_argument("--prior-weight", type=float, default=None,
                   help="how strongly the physically consistent model is pulled toward the URDF's inertials where "
                        "the data are weak (default: 1 for the mixed method, chosen by cross-validation on the fit data for "
                        "the simultaneous method; 0 = data only)")
    p.add_argument("--max-cond", type=float, default=None, help="verdict threshold on the condition number")
    p.add_argument("--max-nrms", type=float, default=None, help="verdict threshold on validation NRMS per axis (0.1 = 10%%)")
    p.add_argument("--strict", action="store_true", help="exit 1 when the verdict fails")
    p.add_argument("--no-report", action="store_true", help="skip report.html (faster)")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bars or summary")
    return p


def main(argv=None) -> int:
    args = parser().parse_args(argv)
    from js2spec.errors import Js2Error

    from identification.pipeline import IdentificationError, IdentifyOptions, identify
    from identification.signals import FilterSettings

    try:
        from js2spec.files import check_output_folder
        check_output_folder(args.outdir)
        opt = IdentifyOptions(
            method=args.method,
            filters=None if args.fc_velocity is None and args.fc_acceleration is None else
            FilterSettings(fc_velocity_hz=args.fc_velocity, fc_acceleration_hz=args.fc_acceleration),
            n_iter=args.iterations or None,
            fit_trials=None if args.fit_trials is None else
            tuple(t.strip() for t in args.fit_trials.split(",") if t.strip()),
            validation_trials=tuple(t.strip() for t in args.validation_trials.split(",") if t.strip()),
            holdout=args.holdout, offsets=args.offsets, sqrt_viscous=args.sqrt_viscous,
            fig3=tuple(t.strip() for t in args.fig3.split(",") if t.strip()),
            progress=not args.quiet, validate_paths=tuple(args.validate), prior_weight=args.prior_weight)
        ident = identify(args.logs, opt)
        for name in opt.fig3:
            ident.param_index(name)
        from identification import output

        out = Path(args.outdir)
        out.mkdir(parents=True, exist_ok=True)
        th = {}
        if args.max_cond is not None:
            th["condition_number_max"] = args.max_cond
        if args.max_nrms is not None:
            th["validation_nrms_max"] = args.max_nrms
        output.write_model(ident, out)
        output.write_urdf(ident, out)
        v = output.write_verdict(ident, out, th)
        if not args.no_report:
            from identification.report import write_report

            write_report(ident, out, v)
    except (Js2Error, IdentificationError) as exc:
        from js2spec.log import damage_notes
        notes = damage_notes([*args.logs, *args.validate])
        why = f" (note: {'; '.join(notes)}: what is missing may have been in the lost part)" if notes else ""
        print(f"js2-identify: error: {exc}{why}", file=sys.stderr)
        return 2
    except ValueError as exc:
        print(f"js2-identify: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:
        print(f"js2-identify: error: {exc.filename or ''}: {exc.strerror or exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("js2-identify: interrupted", file=sys.stderr)
        return 130
    if not args.quiet:
        print(summary(ident, v, out, report=not args.no_report))
    for note in ident.notes:
        if "recovered" in note or "repaired" in note:
            print(f"js2-identify: note: {note}", file=sys.stderr)
    if args.strict and not v["pass"]:
        print("js2-identify: verdict FAILED (see verdict.json)", file=sys.stderr)
        return 1
    return 0


def _g(x) -> str:
    return f"{x:10.4g}" if x == x else f"{'—':>10}"     # NaN (not measured) as a dash


def summary(ident, v, out, report: bool = True) -> str:

    ja, _, alone = ident.motor_inertia()
    lines = [f"method: {ident.chosen}   base parameters: {ident.bp.n}   condition number: {ident.condition_number:.3g}"
             f"   fit samples: {ident.n_fit_samples}"]
    val = ident.validation
    base = val.get("baseline")
    lines.append(f"{'axis':>6} {'f_s':>10} {'f_c':>10} {'B':>10} {'J_a':>10} {'val RMS':>10} {'NRMS':>7}"
                 + (f" {'OLS RMS':>10}" if base else ""))
    for k, j in enumerate(ident.arm.joints):
        lines.append(f"{j:>6} {_g(ident.friction_static[k])} {_g(ident.friction_coulomb[k])} "
                     f"{_g(ident.friction_viscous[k])} {_g(ja[k])}{'' if alone[k] else '*'} "
                     f"{_g(val['rms'][k])} {100 * val['nrms'][k]:6.2f}%" + (f" {_g(base['rms'][k])}" if base else ""))
    if base:
        lines.append(f"validation ({val['samples']} held-out samples): relative torque error js2 "
                     f"{100 * val['rel_overall']:.2f} %, textbook OLS baseline {100 * base['rel_overall']:.2f} % "
                     f"(js2 / OLS = {val['rel_overall'] / base['rel_overall']:.2f})")
    if not all(alone):
        lines.append("  * J_a regrouped with link inertias (see model.yaml motor_inertia_separately_identified)")
    for n in ident.notes:
        lines.append(f"note: {n}")
    files = "model.yaml, robot_identified.urdf, " + ("report.html, " if report else "") + "verdict.json"
    lines.append(f"verdict: {'PASS' if v['pass'] else 'FAIL'}   ->  {out}/ {files}")
    for r in v.get("reasons", []):
        lines.append(f"  FAIL: {r}")
    return "\n".join(lines)


if __name__ == "__main__":
    sys.exit(main())
