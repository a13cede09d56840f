"""The torque-band filter's inner loop (:func:`diagnosis.residual.filtfilt_rows`), compiled.

``scipy.signal.sosfiltfilt`` runs its second-order sections over one series at a time, sample by sample: on the
speed bench's search (up to 96 cogging period counts x 4 columns, each a 140000-sample series) that loop and the
copies around it (odd extension, reversal, state) were about 12 CPU s, most of the filtering the search does. Here
the series are taken 8 at a time (``BLOCK``): the odd extension, the forward pass and the backward pass run through
one small time-major buffer whose inner loop is across the 8 series (no dependence between them, so the compiler
vectorises it) and which stays in the cache. Each series goes through the same IEEE operations, in the same order,
as scipy's ``_sosfilt`` (direct form II transposed; numba's default: no fast-math, no fused multiply-add), so the
numbers are the same to the bit (``tests/test_diag_exact_speedups.py``). 2.5-7x faster than scipy on the search's
batches (12-384 series of 90000-140000 samples).

Array in, array out, no I/O.
"""
from __future__ import annotations

import numpy as np
from numba import njit

BLOCK = 8       # series filtered together (two AVX2 vectors of doubles); the buffer is BLOCK x the extended length


@njit(cache=True, nogil=True)
def _pass(sos: np.ndarray, zi: np.ndarray, buf: np.ndarray, z: np.ndarray, m: int, forward: bool) -> None:
    """One pass of the sections over buf (Le, BLOCK)'s first m columns, in place, from the state zi * the first
    sample of the pass (scipy's ``sosfilt(sos, x, zi=zi * x[0])``)."""
    Le = buf.shape[0]
    S = sos.shape[0]
    first = 0 if forward else Le - 1
    for s in range(S):
        for i in range(m):
            z[s, 0, i] = zi[s, 0, 0] * buf[first, i]
            z[s, 1, i] = zi[s, 0, 1] * buf[first, i]
    for step in range(Le):
        n = step if forward else Le - 1 - step
        for s in range(S):
            b0, b1, b2, a1, a2 = sos[s, 0], sos[s, 1], sos[s, 2], sos[s, 4], sos[s, 5]
            for i in range(m):
                xc = buf[n, i]
                xn = b0 * xc + z[s, 0, i]
                z[s, 0, i] = b1 * xc - a1 * xn + z[s, 1, i]
                z[s, 1, i] = b2 * xc - a2 * xn
                buf[n, i] = xn


@njit(cache=True, nogil=True)
def filtfilt_rows_kernel(sos: np.ndarray, zi: np.ndarray, x: np.ndarray, padlen: int) -> np.ndarray:
    """``scipy.signal.sosfiltfilt(sos, x, axis=-1, padlen=padlen)`` (odd extension) of the rows of x (M, L) float64,
    with zi = ``sosfilt_zi(sos).reshape(len(sos), 1, 2)``; padlen < L. Returns (M, L)."""
    M, L = x.shape
    out = np.empty((M, L))
    filtfilt_rows_into(sos, zi, x, padlen, np.arange(L), out)
    return out


@njit(cache=True, nogil=True)
def filtfilt_rows_into(sos: np.ndarray, zi: np.ndarray, x: np.ndarray, padlen: int, cols: np.ndarray,
                       out: np.ndarray) -> None:
    """:func:`filtfilt_rows_kernel` of x (M, L), written straight into ``out`` (M, len(cols)) at the samples
    ``cols`` (int, increasing, within 0..L-1) only: the filtered series' columns a caller keeps, without the whole
    (M, L) result and the copy that picks them (the same numbers). ``out`` may be a view (any strides)."""
    M, L = x.shape
    S = sos.shape[0]
    Le = L + 2 * padlen
    C = cols.shape[0]
    buf = np.empty((Le, BLOCK))
    z = np.empty((S, 2, BLOCK))
    for i0 in range(0, M, BLOCK):
        m = min(BLOCK, M - i0)
        for k in range(Le):           # the odd extension, as scipy makes it: 2 x[0] - x[padlen..1], x, 2 x[-1] - ...
            for i in range(m):
                r = i0 + i
                if k < padlen:
                    buf[k, i] = 2 * x[r, 0] - x[r, padlen - k]
                elif k < padlen + L:
                    buf[k, i] = x[r, k - padlen]
                else:
                    buf[k, i] = 2 * x[r, L - 1] - x[r, L - 2 - (k - padlen - L)]
        _pass(sos, zi, buf, z, m, True)
        _pass(sos, zi, buf, z, m, False)
        for i in range(m):
            for q in range(C):
                out[i0 + i, q] = buf[cols[q] + padlen, i]
