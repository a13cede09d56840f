"""Random desired trajectories: chained segments (windowed multi-sines, quintic point-to-point moves with rest dwells,
constant-velocity sweeps), each starting and ending at rest. ``draw_trajectory`` gives a JSON description,
``build_trajectory`` evaluates it (positions, velocities, accelerations on a time grid)."""
from __future__ import annotations

import numpy as np

from .arm import NJ, Q_CENTER, Q_HALF

VMAX = np.array([1.0, 0.9, 1.1, 1.5, 1.5, 2.0])   # joint-side speed caps, rad/s (motors 30-70 rad/s)
LO = Q_CENTER - 0.8 * Q_HALF
HI = Q_CENTER + 0.8 * Q_HALF


def _smooth(s):
    """Quintic smoothstep 0 -> 1 with zero 1st and 2nd derivatives at the ends."""
    s = np.clip(s, 0.0, 1.0)
    return s ** 3 * (10 - 15 * s + 6 * s ** 2)


def _rand_pose(rng, frac=0.8):
    return Q_CENTER + frac * Q_HALF * rng.uniform(-1, 1, NJ)


def draw_trajectory(rng, duration, pattern=None):
    """A JSON-able list of segments covering at least ``duration`` seconds (segment types random, or cycling through
    ``pattern``)."""
    p = _rand_pose(rng, 0.5)
    segs = []
    t = 0.0
    start = p.copy()
    while t < duration:
        kind = pattern[len(segs) % len(pattern)] if pattern else rng.choice(["sines", "ptp", "sweep"],
                                                                            p=[0.4, 0.35, 0.25])
        if kind == "sines":
            T = float(rng.uniform(8, 20))
            joints = []
            for j in range(NJ):
                n = int(rng.integers(3, 7))
                f = rng.uniform(0.05, 1.2, n)
                a = rng.uniform(0.2, 1.0, n)
                room = min(p[j] - LO[j], HI[j] - p[j]) * 0.95
                scale = min(room / a.sum(), VMAX[j] / np.sum(a * 2 * np.pi * f) / 1.3)
                a = a * scale * rng.uniform(0.5, 1.0)
                joints.append(dict(freq_hz=f.tolist(), amp_rad=a.tolist(),
                                   phase_rad=rng.uniform(0, 2 * np.pi, n).tolist()))
            segs.append(dict(type="sines", duration_s=T, center=p.tolist(), ramp_s=1.5, joints=joints))
        elif kind == "ptp":
            moves = []
            T = 0.0
            for _ in range(int(rng.integers(2, 6))):
                target = _rand_pose(rng)
                d = np.abs(target - p)
                Tm = float(max(0.8, np.max(1.875 * d / (VMAX * rng.uniform(0.4, 0.9)))))
                dwell = float(rng.uniform(0.2, 1.5))
                moves.append(dict(start=p.tolist(), target=target.tolist(), move_s=Tm, dwell_s=dwell))
                p = target
                T += Tm + dwell
            segs.append(dict(type="ptp", duration_s=T, moves=moves))
        else:
            joints = sorted(rng.choice(NJ, size=int(rng.integers(1, 4)), replace=False).tolist())
            v = VMAX[joints] * rng.uniform(0.1, 0.4, len(joints))
            lo = [float(rng.uniform(LO[j], Q_CENTER[j])) for j in joints]
            hi = [float(rng.uniform(Q_CENTER[j], HI[j])) for j in joints]
            passes = int(rng.integers(2, 5))
            # each joint: go from p to lo, then hi/lo alternately, then back to p; trapezoids with 0.25 s ramps
            legs = []
            for jj, j in enumerate(joints):
                pts = [float(p[j]), lo[jj]] + [hi[jj] if k % 2 == 0 else lo[jj] for k in range(passes)] + [float(p[j])]
                legs.append(pts)
            dist = np.array([sum(abs(b - a) for a, b in zip(pts[:-1], pts[1:])) for pts in legs])
            cruise = dist / v
            if cruise.max() > 18.0:              # keep a sweep segment under ~20 s
                v = np.minimum(v * cruise.max() / 18.0, 0.6 * VMAX[joints])
            v = v.tolist()
            durs = [sum(abs(b - a) / v[jj] + 0.25 for a, b in zip(pts[:-1], pts[1:])) for jj, pts in enumerate(legs)]
            T = float(max(durs) + 0.5)
            segs.append(dict(type="sweep", duration_s=T, center=p.tolist(), joints=joints, speed=v,
                             waypoints=legs, ramp_s=0.25))
        t += segs[-1]["duration_s"]
    return dict(start=start.tolist(), segments=segs)


def build_trajectory(desc, t):
    """Desired q, qd, qdd (N, 6) at times t (uniform grid starting at 0, any step); finite differences of the
    analytic position on a 1 kHz (or finer) internal grid."""
    dt_f = min(1e-3, float(t[1] - t[0]) if len(t) > 1 else 1e-3)
    tf = np.arange(0.0, t[-1] + 3 * dt_f, dt_f)
    q = np.tile(np.asarray(desc["start"], float), (len(tf), 1))
    t0 = 0.0
    for seg in desc["segments"]:
        T = seg["duration_s"]
        m = tf >= t0
        tl = tf[m] - t0
        if seg["type"] == "sines":
            c = np.asarray(seg["center"])
            r = seg["ramp_s"]
            w = _smooth(tl / r) * _smooth((T - tl) / r)
            qq = np.tile(c, (len(tl), 1))
            for j, js in enumerate(seg["joints"]):
                s = np.zeros_like(tl)
                for f, a, ph in zip(js["freq_hz"], js["amp_rad"], js["phase_rad"]):
                    s += a * np.sin(2 * np.pi * f * tl + ph)
                qq[:, j] += w * s
            q[m] = qq
        elif seg["type"] == "ptp":
            tm = 0.0
            qq = np.tile(np.asarray(seg["moves"][-1]["target"]), (len(tl), 1))
            for mv in seg["moves"]:
                a, b = np.asarray(mv["start"]), np.asarray(mv["target"])
                mm = tl >= tm
                s = _smooth((tl[mm] - tm) / mv["move_s"])
                qq[mm] = a + np.outer(s, b - a)
                tm += mv["move_s"] + mv["dwell_s"]
            q[m] = qq
        else:
            c = np.asarray(seg["center"])
            qq = np.tile(c, (len(tl), 1))
            r = seg["ramp_s"]
            for jj, j in enumerate(seg["joints"]):
                v = seg["speed"][jj]
                pts = seg["waypoints"][jj]
                tm = 0.0
                col = np.full(len(tl), pts[-1])
                for a, b in zip(pts[:-1], pts[1:]):
                    D = abs(b - a)
                    Tl = D / v + r
                    mm = tl >= tm
                    x = tl[mm] - tm
                    # smooth trapezoid: speed v*(smooth(x/r) - smooth((x - D/v)/r)); integral in closed form by
                    # numerical cumulative sum on the fine grid
                    spd = v * (_smooth(x / r) - _smooth((x - D / v) / r))
                    pos = np.concatenate([[0.0], np.cumsum(0.5 * (spd[1:] + spd[:-1]) * np.diff(x))]) if len(x) else x
                    pos = np.minimum(pos, D)
                    col[mm] = a + np.sign(b - a) * pos
                    tm += Tl
                qq[:, j] = col
            q[m] = qq
        t0 += T
    qd = np.gradient(q, dt_f, axis=0)
    qdd = np.gradient(qd, dt_f, axis=0)
    idx = np.clip(np.round(t / dt_f).astype(int), 0, len(tf) - 1)
    return q[idx], qd[idx], qdd[idx]
