"""Name the missing physics: fit every candidate term on the fit rows, score it on held-out rows, accept the best
while it improves the held-out fit (a nested-model ladder: the model only grows when data it never saw agree).

Per candidate (term, joint):
1. hyper-parameter (Stribeck velocity, cogging period count, thermal time constant, backlash width) chosen on the
   *fit* rows only (least residual sum of squares);
2. coefficients by weighted least squares on the fit rows of the motors the term can move (each motor's residual
   scaled by its baseline RMS, so small wrist motors count as much as the shoulder);
3. score = held-out gain: 1 - SSE_with_term / SSE_without over every motor's held-out rows (same weights).
The best plausible candidate (ranked by held-out gain over all motors) is accepted if its held-out and its fit gain
on its own motors reach ``min_gain`` (default 12 %) and its gain over all motors ``min_gain_all``; its fitted torque
is then part of the model and the search repeats (at most ``max_terms`` terms).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .library import KINDS, LIBRARY, Fitted, Term
from .residual import ResidualData


@dataclass
class Scored:
    fitted: Fitted
    fit_gain: float              # weighted SSE reduction on the fit rows of the term's motors
    holdout_gain: float          # the same on held-out rows
    holdout_gain_all: float      # held-out, over every motor (ranks terms that move different numbers of motors)
    rms_before: np.ndarray       # (n,) held-out RMS per motor, in the term's band
    rms_after: np.ndarray
    band: str

    def row(self, joints) -> dict:
        f = self.fitted
        return {"kind": f.kind, "joint": joints[f.joint] if f.joint is not None else None, "joint_index": f.joint,
                "hyper": f.hyper, "fit_gain": self.fit_gain, "holdout_gain": self.holdout_gain,
                "holdout_gain_all": self.holdout_gain_all,
                "plausible": f.plausible, "why_not": f.why_not, "summary": f.summary, "effect": f.effect,
                "coefficients": f.coef.tolist(), "coefficients_std": f.coef_std.tolist(), "band": self.band}


def _rms(x: np.ndarray, m: np.ndarray) -> np.ndarray:
    out = np.full(x.shape[1], np.nan)
    for i in range(x.shape[1]):
        if m[:, i].any():
            out[i] = float(np.sqrt(np.mean(x[m[:, i], i] ** 2)))
    return out


def _on_motors(cols: np.ndarray, motors: np.ndarray) -> np.ndarray:
    """A term acts only on the motors it was fitted on: zero its columns elsewhere."""
    out = np.zeros_like(cols)
    out[:, motors] = cols[:, motors]
    return out


class MismatchSearch:
    """Estimator over a :class:`ResidualData`: ``fit`` runs the ladder, ``predict`` gives the accepted terms' torque,
    ``score`` the held-out gain of the accepted terms together."""

    def __init__(self, library: tuple[Term, ...] = LIBRARY, kinds=None, min_gain: float = 0.12, min_gain_all: float = 0.01, max_terms: int = 3,
                 progress=None):
        unknown = set(kinds or ()) - set(KINDS)
        if unknown:
            raise ValueError(f"unknown candidate kinds {sorted(unknown)}; known: {', '.join(KINDS)}")
        self.library = tuple(t for t in library if kinds is None or t.kind in kinds)
        self.min_gain = min_gain
        self.min_gain_all = min_gain_all
        self.max_terms = max_terms
        self.progress = progress

    # -- one candidate ----------------------------------------------------------------------------------------------
    def _evaluate(self, rd: ResidualData, term: Term, j: int, res: dict, weights: dict) -> Scored | None:
        band = term.band
        r = res[band]
        w = weights[band]
        motors = term.motors(rd, j)
        m_fit = rd.mask & rd.fit_rows[:, None]
        m_hold = rd.mask & rd.holdout_rows[:, None]
        sel_fit = np.zeros_like(m_fit)
        sel_fit[:, motors] = m_fit[:, motors]
        if sel_fit.sum() < 20:
            return None
        rw = r * w
        best = None
        for h in term.grid(rd, j):
            cols = _on_motors(term.columns_low(rd, j, h) if band == "low" else term.columns(rd, j, h), motors)
            A = cols[sel_fit] * np.broadcast_to(w, r.shape)[sel_fit][:, None]
            b = rw[sel_fit]
            if not np.any(A):
                continue
            # normal equations on the (k x k) Gram matrix: the columns are few, the rows many
            G = A.T @ A
            coef = np.linalg.lstsq(G, A.T @ b, rcond=None)[0]
            sse = float(np.sum((b - A @ coef) ** 2))
            if best is None or sse < best[0]:
                best = (sse, h, coef, cols, A, b)
        if best is None:
            return None
        sse, h, coef, cols, A, b = best
        dof = max(len(b) - len(coef), 1)
        sigma2 = sse / dof
        try:
            cov = sigma2 * np.linalg.pinv(A.T @ A)   # parameter covariance of the weighted LS
            std = np.sqrt(np.clip(np.diag(cov), 0, None))
        except np.linalg.LinAlgError:
            std = np.full(len(coef), np.inf)
        contrib = cols @ coef                                     # (N, n)
        base_fit = float(np.sum(b ** 2))
        fit_gain = 1.0 - sse / base_fit if base_fit > 0 else 0.0
        new_w = (r - contrib) * w
        sel_hold = np.zeros_like(m_hold)
        sel_hold[:, motors] = m_hold[:, motors]

        def gain(sel):
            s0 = float(np.sum(rw[sel] ** 2))
            return 1.0 - float(np.sum(new_w[sel] ** 2)) / s0 if s0 > 0 else 0.0

        hold_gain, hold_gain_all = gain(sel_hold), gain(m_hold)
        eff, summary, ok, why = term.effect(rd, j, h, coef, std)
        fitted = Fitted(kind=term.kind, joint=j, hyper=None if h is None else float(h), coef=coef, coef_std=std,
                        effect=eff, summary=summary, plausible=bool(ok), why_not=why)
        return Scored(fitted=fitted, fit_gain=fit_gain, holdout_gain=hold_gain, holdout_gain_all=hold_gain_all,
                      rms_before=_rms(r, m_hold), rms_after=_rms(r - contrib, m_hold), band=band)

    # -- the ladder -------------------------------------------------------------------------------------------------
    def fit(self, rd: ResidualData) -> "MismatchSearch":
        res = {"low": np.nan_to_num(rd.residual), "wide": np.nan_to_num(rd.residual_wide)}
        m_fit = rd.mask & rd.fit_rows[:, None]
        weights = {}
        for band, r in res.items():
            rms = _rms(r, m_fit)
            weights[band] = 1.0 / np.where(np.isfinite(rms) & (rms > 0), rms, 1.0)
        self.weights_ = weights
        self.baseline_ = {band: {"fit": _rms(r, m_fit), "holdout": _rms(r, rd.mask & rd.holdout_rows[:, None])}
                          for band, r in res.items()}
        self.accepted_: list[Scored] = []
        self.rankings_: list[list[Scored]] = []
        self.corrections_ = {band: np.zeros_like(r) for band, r in res.items()}
        tasks = [(t, j) for t in self.library for j in (range(rd.n) if t.per_joint else [rd.n - 1])]
        for step in range(self.max_terms):
            scored = []
            it = tasks if self.progress is None else self.progress(tasks, desc=f"diagnosis step {step + 1}")
            for term, j in it:
                if any(a.fitted.kind == term.kind and a.fitted.joint == j for a in self.accepted_):
                    continue
                s = self._evaluate(rd, term, j, res, weights)
                if s is not None:
                    scored.append(s)
            self._nested_check(scored)
            scored.sort(key=lambda s: (s.fitted.plausible, s.holdout_gain_all), reverse=True)
            self.rankings_.append(scored)
            best = next((s for s in scored if s.fitted.plausible), None)
            if (best is None or best.holdout_gain < self.min_gain or best.fit_gain < self.min_gain
                    or best.holdout_gain_all < self.min_gain_all):
                break
            self.accepted_.append(best)
            # the accepted term becomes part of the model, in both bands
            term = next(t for t in self.library if t.kind == best.fitted.kind)
            cols = _on_motors(term.columns(rd, best.fitted.joint, best.fitted.hyper), term.motors(rd, best.fitted.joint))
            raw = cols @ best.fitted.coef
            low = rd.lowpass(raw)
            res["low"] = res["low"] - low
            res["wide"] = res["wide"] - raw
            self.corrections_["low"] += low
            self.corrections_["wide"] += raw
        self.final_ = {band: {"fit": _rms(r, m_fit), "holdout": _rms(r, rd.mask & rd.holdout_rows[:, None])}
                       for band, r in res.items()}
        return self

    def _nested_check(self, scored: list[Scored], margin: float = 0.02) -> None:
        """A term that contains a simpler one (``Term.extends``) must beat it on held-out data by ``margin`` on the
        same joint, or it is not plausible (the simpler physics explains the data as well)."""
        by_key = {(s.fitted.kind, s.fitted.joint): s for s in scored}
        for s in scored:
            term = next(t for t in self.library if t.kind == s.fitted.kind)
            simpler = by_key.get((term.extends, s.fitted.joint)) if term.extends else None
            if simpler is not None and s.holdout_gain < simpler.holdout_gain + margin and s.fitted.plausible:
                s.fitted.plausible = False
                s.fitted.why_not = (f"no better than {term.extends} on held-out data ({s.holdout_gain:.1%} vs "
                                    f"{simpler.holdout_gain:.1%}): the simpler physics explains it")

    def predict(self, rd: ResidualData, band: str = "low") -> np.ndarray:
        """Torque (N, n) the accepted terms add to the model's prediction, in ``band`` ('low' or 'wide')."""
        return self.corrections_[band]

    def score(self, rd: ResidualData, band: str = "low") -> float:
        """Held-out gain (weighted SSE reduction) of all accepted terms together, in ``band``."""
        r0 = np.nan_to_num(rd.residual if band == "low" else rd.residual_wide)
        m = rd.mask & rd.holdout_rows[:, None]
        w = self.weights_[band]
        s0 = float(np.sum((r0 * w)[m] ** 2))
        s1 = float(np.sum(((r0 - self.corrections_[band]) * w)[m] ** 2))
        return 1.0 - s1 / s0 if s0 > 0 else 0.0
