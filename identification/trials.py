"""Trial structure of a js2 log (``/js2/event``): trial spans, segments, breakaways -> sample indices of Signals."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from js2spec.log import segments

from .sequential import Breakaway, VelocitySegment


@dataclass
class TrialSpan:
    name: str
    t0: float
    t1: float
    log_index: int


def trial_spans(events: list[dict], t_end: float, log_index: int = 0) -> list[TrialSpan]:
    """(trial, start, end) from trial_start/trial_end events; an unclosed trial ends at the end of the log."""
    out, open_ = [], {}
    for e in events:
        if e["kind"] == "trial_start":
            open_[e["trial"]] = e["t"]
        elif e["kind"] == "trial_end" and e["trial"] in open_:
            out.append(TrialSpan(e["trial"], open_.pop(e["trial"]), e["t"], log_index))
    for name, t0 in open_.items():
        out.append(TrialSpan(name, t0, t_end, log_index))
    return sorted(out, key=lambda s: s.t0)


def _pose_key(pose) -> tuple:
    return tuple(np.round(np.asarray(pose, float), 3).tolist()) if pose is not None else ()


def breakaways(log, sig, trial: str = "static", move_counts: float = 2.0) -> list[Breakaway]:
    """Breakaway torques of the static test: the ``breakaway`` event in each ramp segment, or, when a segment has
    none, detected from the data: the first cycle whose encoder left the start by one count, confirmed by
    ``move_counts`` counts (the torque is the command applied in the interval it moved in — the command logged one
    cycle earlier — if the log has commands, else the measured torque)."""
    t_end = float(log.feedback.t[-1])
    evs = log.events
    out = []
    fb = log.feedback
    cpr = np.asarray(log.drives.encoder_counts_per_rev, float)
    for seg, t1 in segments(evs, trial, t_end):
        m = seg.get("joint")
        d = seg.get("direction")
        if m is None or d is None:
            continue
        t0 = seg["t"]
        bk = [e for e in evs if e["kind"] == "breakaway" and e.get("trial") == trial and t0 <= e["t"] <= t1
              and e.get("joint", m) == m]
        pose = _pose_key(seg.get("pose"))
        if bk:
            rec = Breakaway(int(m), int(np.sign(d)), float(bk[0]["value"]), pose, float(bk[0]["t"]), True)
            rec.rejected = _check_direction(fb, m, int(np.sign(d)), t0, float(bk[0]["t"]), cpr[m])
            out.append(rec)
            continue
        # the ramp's segment may end at the breakaway itself: look a little past it for the confirmation
        sel = np.flatnonzero((fb.t >= t0) & (fb.t <= t1 + 0.1) & fb.valid[:, m])
        if len(sel) < 3:
            continue
        q = fb.motor_position[sel, m]
        one = (2 * np.pi / cpr[m]) if cpr[m] > 0 else 1e-4
        confirmed = np.flatnonzero(np.abs(q - q[0]) > (move_counts - 0.5) * one)
        if len(confirmed) == 0:
            continue
        # first movement: the first cycle at least one count away, up to the confirmation
        first = np.flatnonzero(np.abs(q[:confirmed[0] + 1] - q[0]) > 0.5 * one)
        moved = first if len(first) else confirmed
        k = sel[moved[0]]
        tau = fb.torque[k, m]
        if log.command is not None:
            # command logged with cycle c is applied from SYNC c+1: the interval ending at SYNC k ran command k-1
            j = np.searchsorted(log.command.cycle, fb.cycle[k] - 1)
            if j < len(log.command.cycle) and log.command.cycle[j] == fb.cycle[k] - 1:
                tau = log.command.target_torque[j, m]
        rec = Breakaway(int(m), int(np.sign(d)), float(tau), pose, float(fb.t[k]), False)
        rec.rejected = _check_direction(fb, m, int(np.sign(d)), t0, float(fb.t[k]), cpr[m])
        out.append(rec)
    return out


def _check_direction(fb, m, direction, t0, t_break, cpr, after_cycles=2) -> str:
    """A breakaway must move the axis the way the ramp pushes: if the motor went the other way (it was sliding,
    e.g. under gravity, before the ramp reached the breakaway torque), the ramp measured nothing (eq. 2 fails).
    Checked from the ramp start to ``after_cycles`` past the breakaway (what follows is the trial's back-off)."""
    i0 = np.searchsorted(fb.t, t0)
    i1 = min(np.searchsorted(fb.t, t_break) + after_cycles, len(fb.t) - 1)
    if i0 >= len(fb.t) or i1 <= i0:
        return ""
    dq = fb.motor_position[i1, m] - fb.motor_position[i0, m]
    one = 2 * np.pi / cpr if cpr > 0 else 1e-4
    if abs(dq) > one and np.sign(dq) != direction:
        return (f"axis moved against the ramp ({dq:+.4g} rad in {fb.t[i1] - fb.t[i0]:.3f} s, direction "
                f"{direction:+d}): not at rest when the ramp started")
    return ""


def velocity_segments(log, sig, trial: str = "velocity", settle_fraction: float = 0.1,
                      speed_tolerance: float = 0.15) -> list[VelocitySegment]:
    """Steady parts of the constant-velocity segments: the middle of each marked segment (``settle_fraction`` cut at
    both ends) where the filtered motor speed is within ``speed_tolerance`` (relative) of the segment's median speed."""
    t_end = float(log.feedback.t[-1])
    out = []
    for seg, t1 in segments(log.events, trial, t_end):
        m = seg.get("joint")
        if m is None:
            continue
        t0 = seg["t"]
        dt = t1 - t0
        sel = np.flatnonzero(sig.mask_between(t0 + settle_fraction * dt, t1 - settle_fraction * dt))
        if len(sel) < 5:
            continue
        w = sig.dq_motor[sel, m]
        med = np.median(w)
        if med == 0:
            continue
        sel = sel[np.abs(w - med) <= speed_tolerance * abs(med)]
        if len(sel) < 5:
            continue
        d = int(np.sign(seg.get("direction", np.sign(med))))
        out.append(VelocitySegment(int(m), d, float(seg.get("speed", abs(med))), sel, sig))
    return out
