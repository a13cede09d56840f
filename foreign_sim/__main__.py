"""python -m foreign_sim --seed N --out DIR | --identification --out DIR"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path


def main(argv=None):
    ap = argparse.ArgumentParser(prog="python -m foreign_sim",
                                 description="Independent Staubli TX40 simulator: writes recording.npz (times, "
                                             "motor-side positions [rad], motor-side torques [N*m]), truth.json "
                                             "and drives.yaml into --out.")
    ap.add_argument("--seed", type=int, help="case seed (random rate, controller, trajectory, concealed effects)")
    ap.add_argument("--identification", action="store_true", help="a clean, richly excited recording instead")
    ap.add_argument("--arm-seed", type=int, default=0, help="seed of the true arm (default 0)")
    ap.add_argument("--rate", type=int, default=500, help="rate of the identification recording (Hz)")
    ap.add_argument("--duration", type=float, default=90.0, help="duration of the identification recording (s)")
    ap.add_argument("--out", type=Path, required=True, help="output directory")
    a = ap.parse_args(argv)
    from .cases import draw_case
    from .record import identification_recording, record_case
    if a.identification:
        print(f"foreign_sim: identification recording -> {a.out}", file=sys.stderr)
        p = identification_recording(a.out, arm_seed=a.arm_seed, rate_hz=a.rate, duration_s=a.duration)
    elif a.seed is not None:
        case = draw_case(a.seed, arm_seed=a.arm_seed)
        print(f"foreign_sim: case {a.seed}: {case['rate_hz']} Hz, {case['duration_s']} s, "
              f"{case['controller']['type']}, effects {[(e['kind'], e['joints']) for e in case['effects']]}",
              file=sys.stderr)
        p = record_case(case, a.out, arm_seed=a.arm_seed)
    else:
        ap.error("give --seed N or --identification")
    t = json.loads((a.out / "truth.json").read_text())
    print(f"foreign_sim: wrote {p} (cpu {t['cpu_s']:.1f} s)", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
