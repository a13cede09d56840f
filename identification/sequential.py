"""The sequential part of the compound method: drive friction axis by axis (eq. 2-5).

Static test (eq. 2-4): at rest ``tau_m = K^T G(theta) + f_s sgn(theta_m_d)``. Ramping one motor's torque up until the
axis moves gives ``tau+``, ramping down gives ``tau-``; then

    f_s = (tau+ - tau-) / 2            (eq. 3)        K^T G(theta) = (tau+ + tau-) / 2      (eq. 4)

Constant-velocity test (eq. 5): ``tau_m - K^T G(theta) = B theta_m_d + f_c sgn(theta_m_d)``: torque against speed is a
line with slope B and intercept f_c (the paper's Fig. 2). The paper takes the gravity term from the static test at the
pose; here the moving axis sweeps angles, so the gravity torque along the sweep is modelled by the gravity columns of
the rigid-body regressor (``K^T Y(theta, 0, 0)``, reduced to its independent directions on the data) and fitted with B
and f_c, pinned by the static test's balance torques (eq. 4) where the log has them. Each steady segment then gives one
Fig. 2 point (mean speed, mean torque minus gravity), and B, f_c and their standard errors come from the line through
those points.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .regressor import ArmModel, rigid_body_regressor


@dataclass
class Breakaway:
    motor: int            # 0-based drive index
    direction: int        # +1 / -1
    torque: float         # N m motor side, the torque at which the axis started moving
    pose: tuple           # joint angles (rad), rounded, identifies the pose
    t: float = 0.0
    from_event: bool = True
    rejected: str = ""    # why this ramp is not a breakaway (empty: valid)


class StaticFrictionTest:
    """Eq. 2-4 from breakaway torques. After ``fit``: ``static_`` (f_s per motor, NaN if untested), ``static_std_``,
    ``gravity_`` (list of dicts motor/pose/torque: the balance torque of eq. 4), ``pairs_`` (count per motor)."""

    def __init__(self, n: int):
        self.n = n

    def fit(self, records: list[Breakaway]):
        by = {}
        self.rejected_ = [r for r in records if r.rejected]
        for r in records:
            if r.rejected:
                continue
            by.setdefault((r.motor, r.pose), {}).setdefault(r.direction, []).append(r.torque)
        fs = [[] for _ in range(self.n)]
        self.gravity_ = []
        for (m, pose), d in sorted(by.items(), key=lambda kv: (kv[0][0], str(kv[0][1]))):
            if 1 in d and -1 in d:
                tp, tn = float(np.mean(d[1])), float(np.mean(d[-1]))
                if tp <= tn:
                    # eq. 3 needs tau+ > tau-: this pose's ramps did not start from rest
                    self.rejected_.append(Breakaway(m, 0, tp - tn, pose, rejected=f"tau+ {tp:.4g} <= tau- {tn:.4g}"))
                    continue
                fs[m].append((tp - tn) / 2.0)                                   # eq. 3
                self.gravity_.append({"motor": m, "pose": list(pose), "torque": (tp + tn) / 2.0,   # eq. 4
                                      "tau_plus": tp, "tau_minus": tn})
        self.static_ = np.array([np.mean(v) if v else np.nan for v in fs])
        self.static_std_ = np.array([np.std(v, ddof=1) / np.sqrt(len(v)) if len(v) > 1 else np.nan for v in fs])
        self.pairs_ = np.array([len(v) for v in fs])
        return self

    def predict(self, motor: int) -> float:
        return float(self.static_[motor])


@dataclass
class VelocitySegment:
    motor: int
    direction: int
    speed: float
    index: np.ndarray          # sample indices (into Signals) of the steady part
    sig: object = None         # the Signals the indices refer to (several logs may hold velocity segments)


@dataclass
class AxisFriction:
    motor: int
    viscous: float
    coulomb: float
    viscous_std: float
    coulomb_std: float
    per_direction: dict = field(default_factory=dict)   # {"+": (B, fc), "-": (B, fc)} when fitted
    points: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))  # (speed, torque - gravity, std)
    n_gravity_columns: int = 0


class ConstantVelocityTest:
    """Eq. 5 per motor. ``fit(arm, signals, segments, balance=None)``; after it ``axes_`` maps motor -> AxisFriction,
    and ``viscous_``, ``coulomb_`` (+ ``_std_``) are per-motor arrays (NaN where the log has no segment)."""

    def __init__(self, n: int, gravity: str = "regressor", rank_rtol: float = 1e-3):
        self.n = n
        self.gravity = gravity
        self.rank_rtol = rank_rtol

    def fit(self, arm: ArmModel, sig, segments: list[VelocitySegment], balance: list[dict] | None = None):
        """``segments`` refer to ``sig`` unless a segment carries its own ``sig`` (segments from several logs)."""
        segments = [s if s.sig is not None else VelocitySegment(s.motor, s.direction, s.speed, s.index, sig)
                    for s in segments]
        self.axes_ = {}
        for m in range(self.n):
            segs = [s for s in segments if s.motor == m and len(s.index) > 2]
            if len(segs) < 2:
                continue
            self.axes_[m] = self._fit_axis(arm, sig, m, segs, [b for b in (balance or []) if b["motor"] == m])
        nan = np.full(self.n, np.nan)
        self.viscous_, self.coulomb_ = nan.copy(), nan.copy()
        self.viscous_std_, self.coulomb_std_ = nan.copy(), nan.copy()
        for m, a in self.axes_.items():
            self.viscous_[m], self.coulomb_[m] = a.viscous, a.coulomb
            self.viscous_std_[m], self.coulomb_std_[m] = a.viscous_std, a.coulomb_std
        return self

    def predict(self, motor: int, speed) -> np.ndarray:
        """Eq. 5: friction torque (N m, motor side) of ``motor`` at motor speeds ``speed`` (rad/s)."""
        w = np.asarray(speed, float)
        return self.viscous_[motor] * w + self.coulomb_[motor] * np.sign(w)

    def score(self, motor: int) -> float:
        """R^2 of the eq. 5 line through the motor's Fig. 2 points."""
        p = self.axes_[motor].points
        r = p[:, 1] - self.predict(motor, p[:, 0])
        return float(1 - np.sum(r ** 2) / np.sum((p[:, 1] - p[:, 1].mean()) ** 2))

    def _gravity_rows(self, arm: ArmModel, q_motor: np.ndarray, m: int) -> np.ndarray:
        qj = arm.joint_from_motor(q_motor)
        z = np.zeros_like(qj)
        Y = rigid_body_regressor(arm, qj, z, z)
        if arm.torque_side == "joint":
            return Y[:, m, :]
        return np.einsum("j,sjp->sp", arm.K[:, m], Y)   # row m of K^T Y

    def _fit_axis(self, arm, sig, m, segs, balance):
        idx = np.concatenate([s.index for s in segs])
        w = np.concatenate([s.sig.dq_motor[s.index, m] for s in segs])
        tau = np.concatenate([s.sig.tau[s.index, m] for s in segs])
        qm = np.concatenate([s.sig.q_motor[s.index] for s in segs])
        G = self._gravity_rows(arm, qm, m) if self.gravity == "regressor" else np.zeros((len(idx), 0))
        rows_g = [G]
        y_extra = []
        if balance:
            poses = np.array([b["pose"] for b in balance], float)
            qm = (poses - arm.joint_offset) @ arm.Kinv.T
            rows_g.append(self._gravity_rows(arm, qm, m))
            y_extra = [b["torque"] for b in balance]
        # independent gravity directions on these samples
        Gall = np.vstack(rows_g)
        U = np.zeros((Gall.shape[1], 0))
        if Gall.size and np.abs(Gall).max() > 0:
            _, s, Vt = np.linalg.svd(Gall, full_matrices=False)
            r = int(np.sum(s > self.rank_rtol * s[0]))
            U = Vt[:r].T
        Gr = G @ U
        # the steady parts are not perfectly steady (the speed loop rings after the ramp): an inertia column takes
        # out J_eff * theta_m_dd so that it does not leak into B or f_c
        acc = np.concatenate([s.sig.ddq_motor[s.index, m] for s in segs])
        Gr = np.column_stack([acc, Gr])
        X = np.column_stack([w, np.sign(w), Gr])
        y = tau
        if balance:
            Xb = np.column_stack([np.zeros(len(y_extra)), np.zeros(len(y_extra)), np.zeros(len(y_extra)),
                                  rows_g[1] @ U])
            # the balance torques are segment-level facts: weight them like a segment's worth of samples
            wt = np.sqrt(max(len(idx) / max(len(segs), 1), 1.0))
            X = np.vstack([X, Xb * wt])
            y = np.concatenate([y, np.asarray(y_extra) * wt])
        sc = np.linalg.norm(X, axis=0)
        sc = np.where(sc > 0, sc, 1.0)
        c, *_ = np.linalg.lstsq(X / sc, y, rcond=None)
        c = c / sc
        grav = Gr @ c[2:]
        # one Fig. 2 point per segment
        pts = []
        off = 0
        for s in segs:
            k = len(s.index)
            r = tau[off:off + k] - grav[off:off + k]
            pts.append((float(np.mean(w[off:off + k])), float(np.mean(r)), float(np.std(r) / np.sqrt(k))))
            off += k
        pts = np.array(pts)
        B, fc, sB, sfc = _line_fit(pts[:, 0], pts[:, 1])
        per_dir = {}
        for name, sgn in (("+", 1), ("-", -1)):
            sel = np.sign(pts[:, 0]) == sgn
            if np.sum(sel) >= 2 and np.ptp(pts[sel, 0]) > 0:
                A = np.column_stack([pts[sel, 0], np.full(np.sum(sel), float(sgn))])
                cd, *_ = np.linalg.lstsq(A, pts[sel, 1], rcond=None)
                per_dir[name] = (float(cd[0]), float(cd[1]))
        return AxisFriction(motor=m, viscous=B, coulomb=fc, viscous_std=sB, coulomb_std=sfc, per_direction=per_dir,
                            points=pts, n_gravity_columns=U.shape[1])


def _line_fit(x, y):
    """Eq. 5 line through Fig. 2 points: y = B x + f_c sgn(x); returns B, f_c and their standard errors."""
    A = np.column_stack([x, np.sign(x)])
    c, *_ = np.linalg.lstsq(A, y, rcond=None)
    r = y - A @ c
    dof = max(len(y) - 2, 1)
    s2 = float(r @ r / dof)
    try:
        cov = np.linalg.inv(A.T @ A) * s2
        se = np.sqrt(np.clip(np.diag(cov), 0, None))
    except np.linalg.LinAlgError:
        se = np.array([np.nan, np.nan])
    return float(c[0]), float(c[1]), float(se[0]), float(se[1])
