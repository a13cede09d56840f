"""The cogging columns' inner loop (:meth:`diagnosis.library.Cogging.grid_columns`), compiled.

For each period count p of a batch the ripple's four columns are sin p theta and cos p theta, once on the rows
turning forward and once on those turning backward, zeroed where the ripple is faster than half the sample rate.
In numpy that is about 15 passes over the recording per p (the angle-addition step, the speed mask, the direction
products): 2-3 CPU s of the speed bench's search. Here one pass per batch writes all of them. The arithmetic is the
numpy code's, operation by operation (numba's default: no fast-math, no fused multiply-add): the same numbers to the
bit (``tests/test_diag_exact_speedups.py``). The sines numpy computes anew (every ``Cogging.RECUR`` period counts and
at a batch's start) are computed by numpy and passed in, since a compiled sine may differ from numpy's in the last
place.

Array in, array out, no I/O.
"""
from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def ripple_columns(periods: np.ndarray, anchor: np.ndarray, sin_anchor: np.ndarray, cos_anchor: np.ndarray,
                   s1: np.ndarray, c1: np.ndarray, fwd: np.ndarray, bwd: np.ndarray, speed: np.ndarray,
                   masked: bool, limit: float, out: np.ndarray) -> None:
    """Fill out (P, 4, L) with [s fwd, c fwd, s bwd, c bwd] of each period count p = periods[i] (P,): s, c = the
    anchor's rows sin_anchor[anchor[i]], cos_anchor[anchor[i]] where anchor[i] >= 0, else sin, cos of (p_prev + 1)
    theta by the angle-addition rule from the previous period count's (s1, c1: sin theta, cos theta). ``masked``:
    fwd and bwd are zeroed on the rows where speed * p > limit (a ripple above half the sample rate, ``limit`` =
    pi fs), as ``fwd * (speed * p <= limit)``."""
    P = periods.shape[0]
    L = s1.shape[0]
    for t in range(L):
        s = 0.0
        c = 0.0
        for i in range(P):
            a = anchor[i]
            if a >= 0:
                s = sin_anchor[a, t]
                c = cos_anchor[a, t]
            else:
                s_next = s * c1[t] + c * s1[t]
                c = c * c1[t] - s * s1[t]
                s = s_next
            f = fwd[t]
            b = bwd[t]
            if masked:
                under = 1.0 if speed[t] * periods[i] <= limit else 0.0
                f = f * under
                b = b * under
            out[i, 0, t] = s * f
            out[i, 1, t] = c * f
            out[i, 2, t] = s * b
            out[i, 3, t] = c * b


@njit(cache=True, nogil=True)
def ripple_dots(periods: np.ndarray, anchor: np.ndarray, sin_anchor: np.ndarray, cos_anchor: np.ndarray,
                s1: np.ndarray, c1: np.ndarray, fwd: np.ndarray, bwd: np.ndarray, speed: np.ndarray,
                masked: bool, limit: float, b: np.ndarray, out: np.ndarray) -> None:
    """out (P, 4) = the sums over the rows of :func:`ripple_columns`' four columns (the same arguments, ``masked``
    and ``limit`` included) times b (L,): each period count's X^T b without its columns (the sines by the same
    anchors and angle-addition steps, so the same column values; the sums in row order, so equal to ``X.T @ b`` to
    rounding). The step is written out as in :func:`ripple_columns` rather than shared through an inlined helper:
    that made both kernels about 3x slower."""
    P = periods.shape[0]
    L = s1.shape[0]
    for i in range(P):
        for k in range(4):
            out[i, k] = 0.0
    for t in range(L):
        s = 0.0
        c = 0.0
        for i in range(P):
            a = anchor[i]
            if a >= 0:
                s = sin_anchor[a, t]
                c = cos_anchor[a, t]
            else:
                s_next = s * c1[t] + c * s1[t]
                c = c * c1[t] - s * s1[t]
                s = s_next
            f = fwd[t] * b[t]
            g = bwd[t] * b[t]
            if masked:
                under = 1.0 if speed[t] * periods[i] <= limit else 0.0
                f = f * under
                g = g * under
            out[i, 0] += s * f
            out[i, 1] += c * f
            out[i, 2] += s * g
            out[i, 3] += c * g
