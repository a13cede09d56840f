#!/usr/bin/env python3
"""Features of a joint's rattle above the torque band, per recording: what stop 38 measured when it looked for a way
to tell a free link's play from its spring (docs/diagnosis.md, stop 38, "measured and not kept").

For joint j of each recording (model and recordings as for js2-diagnose), on its usable fit + select rows:

- ``alpha``: the share of the link's fast inertial torque the motor misses (:class:`diagnosis.library.BacklashRattle`'s
  column, fitted on motor j's unfiltered residual above the band alone), and ``r2``, the share of that residual it
  explains; ``r2_fir``: the same for a 13-tap FIR of the column (a linear, time-invariant link would reach it);
- ``alpha_by_load``: alpha in the thirds of the rows by the link's transmitted torque |tau_j| (low, middle, high) and
  ``load_ratio`` = high / low (a play's link is pushed on a contact when the load is high; a spring's alpha does not
  depend on the load);
- ``alpha_by_swing``: alpha in the lowest and highest third by the swing's envelope;
- ``kurtosis_left``: excess kurtosis of what the one-column fit leaves (impacts are heavy-tailed);
- ``swing_mrad``, ``swing_hz``: the gear's oscillation above the band (peak to peak, joint side) and its frequency.

One JSON line per recording; a recording js2 cannot read is one error line (exit 2 at the end), the others go on.

    .venv/bin/python scripts/rattle_features.py MODEL JOINT REC [REC ...]
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def features(model, path: Path, j: int) -> dict:
    from scipy.signal import hilbert
    from scipy.stats import kurtosis

    from diagnosis.library import BacklashRattle, _gear_side
    from diagnosis.residual import motor_rows, residual_data
    from js2spec.log import join_logs, read_log

    rd = residual_data(model, join_logs([read_log(path)]))
    if not 0 <= j < rd.n:
        raise ValueError(f"joint index {j} outside 0-{rd.n - 1}")
    col = BacklashRattle().columns(rd, j, None)[:, j, 0]
    wide = rd.residual_wide[:, j]
    above = wide - rd.lowpass(wide[:, None])[:, 0]
    m = rd.mask[:, j] & (motor_rows(rd.fit_rows, j) | motor_rows(rd.select_rows, j))
    x, y = col[m], above[m]
    if not np.any(x):
        raise ValueError(f"{rd.joints[j]}: the rattle's column is zero on every usable row")

    def share(sel):
        xx, yy = x[sel], y[sel]
        return float(xx @ yy / (xx @ xx)) if np.any(xx) else float("nan")

    alpha = share(np.ones(len(x), bool))
    left = y - alpha * x
    taps = np.stack([np.roll(col, k) for k in range(-6, 7)], 1)[m]
    coef, *_ = np.linalg.lstsq(taps, y, rcond=None)
    left_fir = y - taps @ coef
    load = np.abs(np.nan_to_num(rd.tau_rigid_joint[:, j]))[m]
    t1, t2 = np.quantile(load, [1 / 3, 2 / 3])
    by_load = [share(load <= t1), share((load > t1) & (load < t2)), share(load >= t2)]
    q_gear = _gear_side(rd, rd.q_motor)[:, j]
    swing = q_gear - rd.lowpass(q_gear[:, None])[:, 0]
    env = rd.lowpass(np.abs(hilbert(swing))[:, None])[:, 0][m]
    e1, e2 = np.quantile(env, [1 / 3, 2 / 3])
    width, f_osc = BacklashRattle.oscillation(rd, j)
    return {"recording": str(path), "joint": rd.joints[j], "sample_rate_hz": rd.fs, "alpha": alpha,
            "r2": 1 - float(left @ left / (y @ y)), "r2_fir": 1 - float(left_fir @ left_fir / (y @ y)),
            "alpha_by_load": by_load, "load_ratio": by_load[2] / by_load[0],
            "alpha_by_swing": [share(env <= e1), share(env >= e2)], "kurtosis_left": float(kurtosis(left)),
            "swing_mrad": 1e3 * width, "swing_hz": f_osc}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("model", type=Path, help="model directory (js2-identify's output) or its model.yaml")
    ap.add_argument("joint", type=int, help="joint index, 0-based (0: the base axis)")
    ap.add_argument("recordings", type=Path, nargs="+", help="MCAP recordings of that arm")
    a = ap.parse_args(argv)
    from js2spec.errors import Js2Error
    from js2spec.model import load_model

    try:
        model = load_model(a.model)
    except (Js2Error, OSError, ValueError) as e:
        print(f"rattle_features: {e}", file=sys.stderr)
        return 2
    failed = 0
    for path in a.recordings:
        try:
            print(json.dumps(features(model, path, a.joint)), flush=True)
        except (Js2Error, OSError, ValueError) as e:
            print(f"rattle_features: {path}: {e}", file=sys.stderr)
            failed += 1
    return 2 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
