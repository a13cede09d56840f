"""``js2-import``: a plain recording (CSV or NumPy) + URDF + drives.yaml -> a js2 log that js2-identify reads."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

DESCRIPTION = """\
Turn another arm's recording into a js2 log (MCAP, spec v1) so that js2-identify can identify it.

You need:
  * the recording: positions and torques (or motor currents), one column per joint, either
      --npz FILE            arrays (default keys: times, positions, torques; see --keys), or
      --positions CSV --torques CSV (or --currents CSV) with --rate HZ / --time-column NAME / --time CSV
  * --urdf FILE             the arm's kinematics and nominal inertials
  * --drives FILE           drives.yaml: joint names (order of the columns), gear-ratio matrix K
                            (q_joint = K q_motor + joint_offset), torque constants, torque_side
                            (motor: motor torques/currents; joint: joint torque sensors)
Positions are motor-side angles unless --positions-side joint.
Mark what the data are with --trial NAME:START:STOP (seconds; repeatable), e.g. a fitting part and a
held-out validation part; default: the whole recording as one 'excitation' trial.
"""

EPILOG = """\
examples:
  # Staubli TX40 (motor side, 5 kHz, coupled wrist), fit on 0-4.95 s, validate on 5.85-9 s
  js2-import --positions pos_read_data.csv --torques curr_data.csv --rate 5000 \\
      --urdf tx40.urdf --drives identification/examples/staubli_tx40/drives.yaml \\
      --trial excitation:0:4.95 --trial validation:5.85:9 -o tx40.mcap
  # KUKA LWR4+ (joint torque sensors, 200 Hz npz)
  js2-import --npz measurements_1.npz --positions-side joint --urdf kuka_lwr4.urdf \\
      --drives identification/examples/kuka_lwr4/drives.yaml -o kuka1.mcap
"""


def parser():
    p = argparse.ArgumentParser(prog="js2-import", description=DESCRIPTION, epilog=EPILOG,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    src = p.add_argument_group("recording")
    src.add_argument("--npz", type=Path, help="NumPy .npz with time, positions and torques/currents arrays")
    src.add_argument("--keys", default="time=times,position=positions,torque=torques",
                     help="npz array names as time=..,position=..,torque=..[,current=..] "
                          "(default: %(default)s)")
    src.add_argument("--positions", type=Path, help="CSV (or .npy) of positions, one column per joint")
    src.add_argument("--torques", type=Path, help="CSV (or .npy) of torques, one column per joint")
    src.add_argument("--currents", type=Path, help="CSV (or .npy) of motor currents, one column per joint")
    src.add_argument("--rate", type=float, help="sample rate in Hz (uniform sampling; also the log's cycle rate)")
    src.add_argument("--time-column", help="name of the time column (s) in the positions CSV")
    src.add_argument("--time", type=Path, help="CSV with the time stamps (s) in its first column")
    src.add_argument("--positions-side", choices=["motor", "joint"], default="motor",
                     help="are the positions motor angles (default) or joint angles")
    src.add_argument("--time-unit", choices=["s", "ms", "us"], default="s",
                     help="unit of the time stamps (default s); a rate that is not a servo rate is refused with a hint")
    p.add_argument("--nan", choices=["mark", "refuse"], default="mark",
                   help="samples with missing/NaN values: mark them invalid (default; the count is printed) or refuse")
    p.add_argument("--no-unit-check", action="store_true",
                   help="skip the check of the torques' units against the nominal URDF (a factor like 1000, 180/pi "
                        "or a gear ratio is refused otherwise)")
    p.add_argument("--urdf", type=Path, required=True, help="URDF of the arm")
    p.add_argument("--drives", type=Path, required=True, help="drives.yaml of the arm (keys of the js2 log spec)")
    p.add_argument("--trial", action="append", default=[], metavar="NAME:START:STOP",
                   help="a trial of the recording, seconds from its start (repeatable)")
    p.add_argument("--rows", help="import only rows A:B of the recording")
    p.add_argument("--robot", help="robot name in the log (default: the drives file's folder name)")
    p.add_argument("-o", "--output", type=Path, required=True, help="the js2 log to write (.mcap)")
    return p


def main(argv=None) -> int:
    args = parser().parse_args(argv)
    from js2spec.drives import load_drives
    from js2spec.errors import Js2Error

    from identification import importer as im

    try:
        drives = load_drives(args.drives)
        if args.npz:
            keys = dict(kv.split("=", 1) for kv in args.keys.split(",") if "=" in kv)
            rec = im.load_npz(args.npz, keys.get("time", "times"), keys.get("position", "positions"),
                              keys.get("torque"), keys.get("current"))
        elif args.positions:
            rec = im.load_csvs(args.positions, args.torques, args.currents, args.rate, args.time, args.time_column,
                               n=drives.n)
        else:
            raise im.ImportError_("give the recording: --npz FILE, or --positions CSV with --torques/--currents CSV")
        trials = []
        for spec in args.trial:
            parts = spec.split(":")
            if len(parts) != 3:
                raise im.ImportError_(f"--trial {spec!r}: expected NAME:START:STOP (seconds)")
            try:
                trials.append((parts[0], float(parts[1]), float(parts[2])))
            except ValueError:
                raise im.ImportError_(f"--trial {spec!r}: START and STOP must be numbers (seconds)") from None
        rows = None
        if args.rows:
            a, b = args.rows.split(":")
            rows = (int(a) if a else None, int(b) if b else None)
        if args.output.is_dir():
            raise im.ImportError_(f"-o {args.output}: is a folder; give a file name, e.g. {args.output / 'rec.mcap'}")
        if not args.output.parent.is_dir():
            raise im.ImportError_(f"-o {args.output}: the folder {args.output.parent} does not exist; create it first")
        report: dict = {}
        out = im.write_log(rec, args.urdf, args.drives, args.output, robot=args.robot, rate=args.rate,
                           positions_side=args.positions_side, trials=trials or None, rows=rows,
                           time_unit=args.time_unit, nan_policy=args.nan, unit_check=not args.no_unit_check,
                           report=report)
    except Js2Error as exc:
        print(f"js2-import: error: {exc}", file=sys.stderr)
        return 2
    except (ValueError, OSError) as exc:
        print(f"js2-import: error: {exc}", file=sys.stderr)
        return 2
    print(f"js2-import: wrote {out} ({len(rec.t)} samples at {report['rate_hz']:.6g} Hz, {drives.n} joints, "
          f"torque side {drives.torque_side})")
    if report["nan_rows"]:
        print(f"js2-import: {report['nan_rows']} samples with missing/NaN values marked invalid (--nan refuse to "
              f"stop instead)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
