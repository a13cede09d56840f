"""Locate a mismatch: which motor carries the residual, and in which regime of the motion.

For every motor: the held-out residual RMS (torque band) before and after the terms the search accepted, and the
residual broken down by regime — slow / medium / fast speed, forward / backward,
the first 0.25 s after the joint's transmitted torque reverses, and the early / middle / late third of the
recording — so that "where" reads like "motor 2, at low speed" or "motor 1, late in the run".
"""
from __future__ import annotations

import numpy as np

from .residual import ResidualData

SPEED_BANDS = ((0.0, 10.0, "slow (<10 rad/s)"), (10.0, 50.0, "medium (10-50 rad/s)"), (50.0, np.inf, "fast (>50 rad/s)"))


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(x ** 2))) if len(x) else float("nan")


def regimes(rd: ResidualData, i: int) -> dict[str, np.ndarray]:
    """Boolean row masks (N,) of the regimes of motor ``i``."""
    w = np.nan_to_num(rd.dq_motor[:, i])
    out = {}
    for lo, hi, name in SPEED_BANDS:
        out[name] = (np.abs(w) >= lo) & (np.abs(w) < hi)
    out["forward"] = w > 0
    out["backward"] = w < 0
    j = int(np.argmax(np.abs(rd.K[:, i])))                     # the joint this motor mostly drives
    tau = np.sign(np.nan_to_num(rd.tau_rigid_joint[:, j]))
    flips = np.flatnonzero((tau[1:] != tau[:-1]) & (tau[1:] != 0)) + 1
    after = np.zeros(len(w), dtype=bool)
    span = int(0.25 * rd.fs)
    for k in flips:
        after[k:k + span] = True
    out["after torque reversal (0.25 s)"] = after
    t = rd.t
    cuts = np.quantile(t, [1 / 3, 2 / 3])
    out["early third"] = t < cuts[0]
    out["middle third"] = (t >= cuts[0]) & (t < cuts[1])
    out["late third"] = t >= cuts[1]
    return out


def locate(rd: ResidualData, search=None, min_drop: float = 0.10) -> dict:
    """Per motor: held-out residual RMS before and after the found terms, the regime where the residual is largest
    relative to the motor's overall level, and whether the motor is where the mismatch is (``flagged``: the accepted
    terms cut its held-out residual by at least ``min_drop``, or — with nothing accepted — a candidate term reaches
    the search's ``min_gain`` on the select rows without passing every other test). RMS figures: report rows."""
    r = np.nan_to_num(rd.residual)
    rows = rd.fit_rows | rd.holdout_rows
    m = rd.mask & rows[:, None]
    mh = rd.mask & rd.holdout_rows[:, None]
    before = np.array([_rms(r[mh[:, i], i]) for i in range(rd.n)])
    if search is not None:
        corr = search.predict(rd, "low")
        after = np.array([_rms((r - corr)[mh[:, i], i]) for i in range(rd.n)])
        best_gain = np.zeros(rd.n)
        for sc in (search.rankings_[0] if search.rankings_ else []):
            if not sc.fitted.plausible:
                continue
            for i in sc.fitted.effect.get("joints", []):
                best_gain[i] = max(best_gain[i], sc.select_gain)
    else:
        after, best_gain = before.copy(), np.zeros(rd.n)
    drop = 1 - after / np.where(before > 0, before, np.nan)
    motors = []
    for i in range(rd.n):
        overall = _rms(r[m[:, i], i])
        reg = {}
        for name, mask in regimes(rd, i).items():
            sel = m[:, i] & mask
            if sel.sum() >= 50:
                reg[name] = {"rms": _rms(r[sel, i]), "samples": int(sel.sum()),
                             "ratio": _rms(r[sel, i]) / overall if overall > 0 else float("nan")}
        worst = max(reg.items(), key=lambda kv: kv[1]["ratio"])[0] if reg else None
        accepted = bool(search is not None and search.accepted_)
        flagged = (bool(drop[i] >= min_drop) if accepted
                   else bool(search is not None and best_gain[i] >= search.min_gain))
        motors.append({"motor": i, "joint": rd.joints[i],
                       "holdout_rms_before": float(before[i]), "holdout_rms_after": float(after[i]),
                       "holdout_drop": float(drop[i]), "regimes": reg, "worst_regime": worst, "flagged": flagged})
    flagged = [d for d in motors if d["flagged"]]
    if flagged:
        parts = []
        for d in sorted(flagged, key=lambda d: -d["holdout_drop"]):
            wr = d["worst_regime"]
            extra = f"; largest {wr} ({d['regimes'][wr]['ratio']:.1f}x its overall level)" if wr else ""
            parts.append(f"motor {d['motor'] + 1} ({d['joint']}): held-out residual {d['holdout_rms_before']:.3g} "
                         f"-> {d['holdout_rms_after']:.3g} N*m{extra}")
        text = "; ".join(parts)
    else:
        text = "no motor carries a residual that a candidate term explains"
    return {"motors": motors, "flagged": [d["motor"] for d in flagged], "text": text, "min_drop": min_drop}
