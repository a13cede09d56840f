"""Linear estimators for ``y = H theta`` with sample blocks (one block of n rows per sample), scikit-learn style.

* :class:`RecursiveLeastSquares` — the paper's RLS (simultaneous part), with its convergence history.
* :class:`BatchLeastSquares` — ordinary / weighted least squares with standard errors.

Shapes: ``H`` is (N, m, p) (N samples, m rows per sample, e.g. one per motor) or (N, p); ``y`` is (N, m) or (N,);
``sample_weight`` (same shape as ``y``) weights rows (0 excludes a row, e.g. an axis near zero speed).

Standard errors: ``sigma^2 (H^T H)^-1`` assumes independent rows. Rows of low-pass filtered signals are not: a
zero-phase filter of cut-off fc at sample rate fs leaves about ``2 fc / fs`` independent samples per sample, so the
pipeline passes ``correlation_length = fs / (2 fc)`` and the variances are multiplied by it (default 1: white rows).

Why not filterpy's ``KalmanFilter`` in the loop: a Kalman filter with a constant state (F = I, Q = 0), the regressor
block as its measurement matrix H and R = I *is* RLS, and ``RecursiveLeastSquares(method="recursive")`` runs exactly
that update (tests check it equals filterpy's ``KalmanFilter.update`` on a small case). But 35,000 Python-level
updates of a ~50-parameter covariance cost ~1 s; the default ``method="block"`` uses the algebraically identical
information form

    P_k^-1 = P_0^-1 + sum_{s<=k} H_s^T W_s H_s,     theta_k = P_k (P_0^-1 theta_0 + sum_{s<=k} H_s^T W_s y_s)

accumulated with vectorised sums between checkpoints. It returns the same estimate after every checkpoint as the
recursion does after that many samples (to rounding; tests check), keeps the history at ``n_checkpoints`` evenly spaced
iterations, and costs one (p x p) solve per checkpoint.
"""
from __future__ import annotations

import numpy as np
import scipy.linalg as sla


def _as_blocks(H, y, w):
    H = np.asarray(H, float)
    y = np.asarray(y, float)
    if H.ndim == 2:
        H = H[:, None, :]
        y = y[:, None]
    if w is None:
        w = np.ones_like(y)
    else:
        w = np.asarray(w, float).reshape(y.shape)
    return H, y, w


class RecursiveLeastSquares:
    """RLS over sample blocks; after ``fit``: ``coef_``, ``cov_`` (P), ``std_``, ``history_``, ``history_iter_``.

    Parameters: ``n_iter`` samples used (default 35,000 as in the paper; all samples if fewer; ``None`` = all),
    ``p0`` prior covariance scale (in column-normalised units: P_0 = p0 * diag(1/s_j^2) with s_j the RMS of column j,
    so the prior is equally weak for every parameter), ``theta0`` initial estimate (default 0), ``method``
    ``"block"`` (default, vectorised information form) or ``"recursive"`` (the textbook per-sample update),
    ``n_checkpoints`` history length.
    """

    def __init__(self, n_iter: int | None = 35000, p0: float = 1e6, theta0=None, method: str = "block",
                 n_checkpoints: int = 200, P0=None, correlation_length: float = 1.0):
        self.correlation_length = correlation_length
        self.n_iter = n_iter
        self.p0 = p0
        self.theta0 = theta0
        self.method = method
        self.n_checkpoints = n_checkpoints
        self.P0 = P0

    def _prior(self, H, w):
        p = H.shape[-1]
        if self.P0 is not None:
            P0 = np.asarray(self.P0, float)
        else:
            ss = np.zeros(p)
            for c0 in range(0, len(H), 8192):
                ss += np.einsum("sm,smp->p", w[c0:c0 + 8192], H[c0:c0 + 8192] ** 2)
            s = np.sqrt(ss / max(w.sum(), 1.0))
            s = np.where(s > 0, s, 1.0)
            P0 = np.diag(self.p0 / s ** 2)
        th0 = np.zeros(p) if self.theta0 is None else np.asarray(self.theta0, float)
        return P0, th0

    def fit(self, H, y, sample_weight=None, progress=None):
        H, y, w = _as_blocks(H, y, sample_weight)
        N = H.shape[0] if self.n_iter is None else min(self.n_iter, H.shape[0])
        H, y, w = H[:N], y[:N], w[:N]
        P0, th0 = self._prior(H, w)
        if self.method == "recursive":
            self._fit_recursive(H, y, w, P0, th0, progress)
        elif self.method == "block":
            self._fit_block(H, y, w, P0, th0, progress)
        else:
            raise ValueError(f"unknown RLS method {self.method!r} (block | recursive)")
        r = (y - np.einsum("smp,p->sm", H, self.coef_)) * np.sqrt(w)
        dof = max(int(np.sum(w > 0)) - H.shape[-1], 1)
        self.sigma2_ = float(np.sum(r ** 2) / dof)
        self.std_ = np.sqrt(np.clip(np.diag(self.cov_), 0, None) * self.sigma2_ * self.correlation_length)
        self.n_iter_ = N
        return self

    def _checkpoints(self, N):
        k = np.unique(np.linspace(0, N, self.n_checkpoints + 1).round().astype(int))
        return k[k > 0]

    def _fit_recursive(self, H, y, w, P0, th0, progress):
        P = P0.copy()
        th = th0.copy()
        cps = set(self._checkpoints(len(H)).tolist())
        hist, hit = [], []
        it = range(len(H)) if progress is None else progress(range(len(H)))
        for s in it:
            keep = w[s] > 0
            if keep.any():
                Hs = H[s][keep]
                R = np.diag(1.0 / w[s][keep])
                S = Hs @ P @ Hs.T + R
                Kg = P @ Hs.T @ np.linalg.inv(S)
                th = th + Kg @ (y[s][keep] - Hs @ th)
                P = P - Kg @ Hs @ P
                P = 0.5 * (P + P.T)
            if s + 1 in cps:
                hist.append(th.copy())
                hit.append(s + 1)
        self.coef_, self.cov_ = th, P
        self.history_, self.history_iter_ = np.array(hist), np.array(hit)

    def _fit_block(self, H, y, w, P0, th0, progress):
        p = H.shape[-1]
        Pinv0 = np.linalg.inv(P0)
        A = Pinv0.copy()
        b = Pinv0 @ th0
        cps = self._checkpoints(len(H))
        hist = np.empty((len(cps), p))
        prev = 0
        sq = np.sqrt(w)
        it = enumerate(cps) if progress is None else progress(list(enumerate(cps)))
        # scale for a well-conditioned solve
        for i, k in it:
            Hb = (H[prev:k] * sq[prev:k, :, None]).reshape(-1, p)
            yb = (y[prev:k] * sq[prev:k]).reshape(-1)
            A += Hb.T @ Hb
            b += Hb.T @ yb
            d = np.sqrt(np.diag(A))
            d = np.where(d > 0, d, 1.0)
            An = A / np.outer(d, d)
            hist[i] = sla.solve(An, b / d, assume_a="pos") / d
            prev = k
        d = np.sqrt(np.diag(A))
        An = A / np.outer(d, d)
        self.coef_ = hist[-1].copy()
        self.cov_ = np.linalg.inv(An) / np.outer(d, d)
        self.history_, self.history_iter_ = hist, cps

    def predict(self, H):
        H = np.asarray(H, float)
        return H @ self.coef_

    def score(self, H, y, sample_weight=None):
        """Coefficient of determination R^2 over all (weighted) rows."""
        H, y, w = _as_blocks(H, y, sample_weight)
        r = y - np.einsum("smp,p->sm", H, self.coef_)
        yy = y - np.sum(w * y) / np.sum(w)
        return float(1 - np.sum(w * r ** 2) / np.sum(w * yy ** 2))


class BatchLeastSquares:
    """Batch OLS (``weighting="ols"``) or WLS (``"wls"``: rows of motor j weighted by 1/sigma_j^2 with sigma_j the
    OLS residual RMS of motor j, Gautier's WLS). After ``fit``: ``coef_``, ``cov_``, ``std_``, ``sigma_`` (per row
    type)."""

    def __init__(self, weighting: str = "ols", correlation_length: float = 1.0):
        self.weighting = weighting
        self.correlation_length = correlation_length

    def fit(self, H, y, sample_weight=None):
        H, y, w = _as_blocks(H, y, sample_weight)
        p = H.shape[-1]
        coef, cov, sig = self._solve(H, y, w)
        if self.weighting == "wls":
            r = (y - np.einsum("smp,p->sm", H, coef))
            sig_j = np.sqrt(np.sum(w * r ** 2, axis=0) / np.maximum(np.sum(w > 0, axis=0), 1))
            sig_j = np.where(sig_j > 0, sig_j, 1.0)
            coef, cov, _ = self._solve(H, y, w / sig_j[None, :] ** 2)
            self.sigma_ = sig_j
            self.std_ = np.sqrt(np.clip(np.diag(cov), 0, None))
        elif self.weighting == "ols":
            self.sigma_ = np.array([np.sqrt(sig)])
            self.std_ = np.sqrt(np.clip(np.diag(cov) * sig, 0, None))
        else:
            raise ValueError(f"unknown weighting {self.weighting!r} (ols | wls)")
        self.coef_, self.cov_ = coef, (cov if self.weighting == "wls" else cov * sig) * self.correlation_length
        self.std_ = self.std_ * np.sqrt(self.correlation_length)
        self.n_params_ = p
        return self

    @staticmethod
    def _solve(H, y, w):
        """Weighted normal equations on column-normalised rows (Cholesky; pseudo-inverse if rank-deficient),
        accumulated over sample chunks (no full copy of the weighted regressor)."""
        p = H.shape[-1]
        G = np.zeros((p, p))
        g = np.zeros(p)
        bb = 0.0
        n_rows = 0
        for c0 in range(0, len(H), 8192):
            sq = np.sqrt(w[c0:c0 + 8192])
            A = (H[c0:c0 + 8192] * sq[:, :, None]).reshape(-1, p)
            b = (y[c0:c0 + 8192] * sq).reshape(-1)
            G += A.T @ A
            g += A.T @ b
            bb += float(b @ b)
            n_rows += int(np.sum(np.any(A != 0, axis=1)))
        d = np.sqrt(np.diag(G))
        d = np.where(d > 0, d, 1.0)
        Gn = G / np.outer(d, d)
        try:
            Ginv = sla.cho_solve(sla.cho_factor(Gn), np.eye(p))
        except np.linalg.LinAlgError:
            Ginv = np.linalg.pinv(Gn)
        coef = (Ginv @ (g / d)) / d
        rss = float(bb - 2 * coef @ g + coef @ G @ coef)
        dof = max(n_rows - p, 1)
        sig = max(rss, 0.0) / dof
        cov = Ginv / np.outer(d, d)
        return coef, cov, sig

    def predict(self, H):
        return np.asarray(H, float) @ self.coef_

    def score(self, H, y, sample_weight=None):
        H, y, w = _as_blocks(H, y, sample_weight)
        r = y - np.einsum("smp,p->sm", H, self.coef_)
        yy = y - np.sum(w * y) / np.sum(w)
        return float(1 - np.sum(w * r ** 2) / np.sum(w * yy ** 2))
