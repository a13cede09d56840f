"""Normal equations of several candidate terms at once, for estimating the accepted findings together after the
search's ladder (``MismatchSearch._joint_refit``): array in, arrays out, no I/O."""
from __future__ import annotations

import numpy as np


class JointNormalEquations:
    """Several terms' weighted columns ``A`` (N, n, K: term k owns columns ``edges[k]:edges[k + 1]``) against a
    weighted residual ``b`` (N, n). For each part of the rows (``masks``: name -> (N, n) bool, e.g. fit, select and
    report) and each motor it keeps G = A'A (K, K), A'b (K,), b'b and the row count, so that the least squares of
    any subset of the terms, and its squared error per motor on any part, cost K x K algebra instead of a pass over
    the samples."""

    def __init__(self, A: np.ndarray, b: np.ndarray, masks: dict, sizes):
        self.A = A
        self.edges = np.cumsum([0] + [int(s) for s in sizes])
        n, K = A.shape[1], A.shape[2]
        self.parts = {}
        for name, m in masks.items():
            G, Ab, bb = np.zeros((n, K, K)), np.zeros((n, K)), np.zeros(n)
            for i in range(n):
                a_i, b_i = A[m[:, i], i, :], b[m[:, i], i]
                G[i], Ab[i], bb[i] = a_i.T @ a_i, a_i.T @ b_i, b_i @ b_i
            self.parts[name] = (G, Ab, bb, m.sum(axis=0))

    def index(self, subset) -> np.ndarray:
        """The columns of the terms ``subset`` (in that order)."""
        if not len(subset):
            return np.array([], dtype=int)
        return np.concatenate([np.arange(self.edges[k], self.edges[k + 1]) for k in subset]).astype(int)

    def gram(self, ix: np.ndarray, parts) -> np.ndarray:
        """A'A of the columns ``ix`` over every motor and the rows of ``parts``."""
        return sum(self.parts[p][0].sum(axis=0) for p in parts)[np.ix_(ix, ix)]

    def solve(self, subset, parts) -> tuple[np.ndarray, np.ndarray]:
        """(columns, coefficients) of the least squares of the terms ``subset`` on the rows of ``parts`` (no terms: no
        columns and no coefficients, whose ``sse`` is the residual's own)."""
        ix = self.index(subset)
        Ab = sum(self.parts[p][1].sum(axis=0) for p in parts)[ix]
        return ix, np.linalg.lstsq(self.gram(ix, parts), Ab, rcond=None)[0]

    def sse(self, part: str, ix: np.ndarray, coef: np.ndarray) -> np.ndarray:
        """(n,) the weighted squared error per motor on the rows ``part`` left by the columns ``ix`` times ``coef``."""
        G, Ab, bb, _ = self.parts[part]
        if len(ix) == 0:
            return bb.copy()
        n = len(bb)
        return np.maximum(bb - 2 * Ab[:, ix] @ coef + np.einsum("k,mkl,l->m", coef, G[np.ix_(range(n), ix, ix)], coef),
                          0.0)

    def rows(self, part: str) -> np.ndarray:
        """(n,) the number of rows of ``part`` per motor."""
        return self.parts[part][3]

    def std(self, ix: np.ndarray, coef: np.ndarray, parts) -> np.ndarray:
        """Standard errors of ``coef`` fitted on ``parts`` (the weighted least squares' covariance)."""
        rows = int(sum(self.rows(p).sum() for p in parts))
        resid = float(sum(self.sse(p, ix, coef).sum() for p in parts))
        cov = resid / max(rows - len(ix), 1) * np.linalg.pinv(self.gram(ix, parts))
        return np.sqrt(np.clip(np.diag(cov), 0, None))
