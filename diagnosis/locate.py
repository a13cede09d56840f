"""Locate a mismatch: which motor carries the residual, and in which regime of the motion.

For every motor: the held-out residual RMS (torque band) before and after the terms the search accepted, and the
residual broken down by regime — slow / medium / fast speed, forward / backward,
the first 0.25 s after the joint's transmitted torque reverses, and the early / middle / late third of the
recording — and by frequency band (:func:`band_shares` of what the found terms leave), so that "where" reads like
"motor 2, at low speed" or "motor 1, late in the run, below 0.5 Hz".
"""
from __future__ import annotations

import numpy as np
from scipy.signal import periodogram

from .residual import ResidualData, part_rows

# frequency bands of a residual, Hz: what each usually holds on an arm moved by smooth trials
FREQUENCY_BANDS = ((0.0, 0.5, "below 0.5 Hz (drift, slow trends)"), (0.5, 2.0, "0.5-2 Hz (the motion's own rate)"),
                   (2.0, 7.0, "2-7 Hz (the torque band's top)"), (7.0, 20.0, "7-20 Hz (above the torque band)"),
                   (20.0, np.inf, "above 20 Hz (ripple, resonance, noise)"))


def band_shares(x: np.ndarray, fs: float, valid: np.ndarray | None = None) -> dict[str, float]:
    """Share of the power of ``x`` ((N,), e.g. a residual in N*m sampled at ``fs`` Hz) in each of
    ``FREQUENCY_BANDS`` (one Hann-windowed periodogram of the whole record, mean removed, so a drift over
    minutes counts as slow; samples where ``valid`` is False count as 0,
    so a gap adds no power). Bands above the Nyquist frequency are left out; shares sum to 1 (empty dict when
    ``x`` has no power)."""
    x = np.where(valid, np.nan_to_num(x), 0.0) if valid is not None else np.nan_to_num(np.asarray(x, dtype=float))
    if len(x) < 16:
        return {}
    f, p = periodogram(x, fs=fs, window="hann", detrend="constant")
    total = float(np.sum(p))
    if total <= 0:
        return {}
    return {name: float(np.sum(p[(f >= lo) & (f < hi)]) / total) for lo, hi, name in FREQUENCY_BANDS if lo < fs / 2}


def dominant_band(shares: dict[str, float]) -> tuple[str | None, float]:
    """The band holding the most power, and its share."""
    if not shares:
        return None, float("nan")
    name = max(shares, key=shares.get)
    return name, shares[name]


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
    """Per motor: held-out residual RMS before and after the found terms (in the motor's band,
    ``MismatchSearch.motor_bands``: unfiltered where a finding was proven unfiltered), the regime where the residual
    is largest relative to the motor's overall level, the frequency bands of what the found terms leave on it (wide
    band, every valid row: :func:`band_shares`), and whether the motor is where the mismatch is (``flagged``: the accepted
    terms cut its held-out residual by at least ``min_drop``, or — with nothing accepted — a candidate term reaches
    the search's ``min_gain`` on the select rows without passing every other test). RMS figures: report rows."""
    r = np.nan_to_num(rd.residual)
    m = rd.mask & (part_rows(rd.fit_rows, rd.n) | part_rows(rd.holdout_rows, rd.n))
    mh = rd.mask & part_rows(rd.holdout_rows, rd.n)
    # each motor's before/after in the band its findings were proven in (a play's rattle, cogging ripple: unfiltered)
    motor_band = search.motor_bands(rd) if search is not None else ["low"] * rd.n
    r_band = {"low": r, "wide": np.nan_to_num(rd.residual_wide)}
    left = {b: x - search.predict(rd, b) for b, x in r_band.items()} if search is not None else r_band
    before = np.array([_rms(r_band[motor_band[i]][mh[:, i], i]) for i in range(rd.n)])
    after = np.array([_rms(left[motor_band[i]][mh[:, i], i]) for i in range(rd.n)])
    best_gain = np.zeros(rd.n)
    if search is not None:
        for sc in (search.rankings_[0] if search.rankings_ else []):
            if not sc.fitted.plausible:
                continue
            for i in sc.fitted.effect.get("joints", []):
                best_gain[i] = max(best_gain[i], sc.select_gain)
    left_wide = left["wide"]
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
        bands = band_shares(left_wide[:, i], rd.fs, rd.mask[:, i])
        band, band_share = dominant_band(bands)
        accepted = bool(search is not None and search.accepted_)
        flagged = (bool(drop[i] >= min_drop) if accepted
                   else bool(search is not None and best_gain[i] >= search.min_gain))
        motors.append({"motor": i, "joint": rd.joints[i], "band": motor_band[i],
                       "holdout_rms_before": float(before[i]), "holdout_rms_after": float(after[i]),
                       "holdout_drop": float(drop[i]), "regimes": reg, "worst_regime": worst,
                       "frequency_bands": bands, "dominant_band": band,
                       "dominant_band_share": float(band_share) if band is not None else None,
                       "flagged": flagged})
    flagged = [d for d in motors if d["flagged"]]
    if flagged:
        parts = []
        for d in sorted(flagged, key=lambda d: -d["holdout_drop"]):
            wr = d["worst_regime"]
            extra = f"; largest {wr} ({d['regimes'][wr]['ratio']:.1f}x its overall level)" if wr else ""
            unf = " (unfiltered)" if d["band"] == "wide" else ""
            parts.append(f"motor {d['motor'] + 1} ({d['joint']}): held-out residual{unf} "
                         f"{d['holdout_rms_before']:.3g} -> {d['holdout_rms_after']:.3g} N*m{extra}")
        text = "; ".join(parts)
    else:
        text = "no motor carries a residual that a candidate term explains"
    return {"motors": motors, "flagged": [d["motor"] for d in flagged], "text": text, "min_drop": min_drop}
