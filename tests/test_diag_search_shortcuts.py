"""Stop 40's shortcuts in the search give the search's numbers: a grid point's SSE from its normal equations
(``MismatchSearch._solve``), the gains' sums of squares from 1.0 / 0.0 masks (``MismatchSearch._float_masks``),
the rigid-body regressor kept as a view of the whole regressor (``residual_data``), and the torque band's filter
writing only the samples a caller keeps (``ResidualData.lowpass_series(..., keep=)``)."""
import json

import numpy as np
import pytest

from diagnosis.residual import part_rows
from fixtures_diag import clean_model, recording


def _explicit(A, b, coef):
    return float(np.sum((b - A @ coef) ** 2))


@pytest.mark.parametrize("seed", range(4))
def test_normal_equations_sse_is_the_residuals(seed):
    """Columns of very different scales. Where a fit leaves 0.1 % of b'b or more (the least the speed bench's search
    met was 0.1 %) the SSE is the residual's sum of squares to 1e-9 relative; where it leaves almost nothing the
    difference is rounding of b'b (at most 1e-12 of it). The coefficients are lstsq's on the Gram matrix."""
    from diagnosis.search import MismatchSearch

    rng = np.random.default_rng(seed)
    A = rng.normal(size=(5000, 4)) * np.array([1.0, 1e-3, 30.0, 0.2])
    for share in (1e-3, 0.5, 1e-9):
        signal = A @ rng.normal(size=4)
        noise = rng.normal(size=5000)
        noise *= np.sqrt(share / (1 - share) * float(signal @ signal) / float(noise @ noise))
        b = signal + noise
        bb = float(b @ b)
        G = A.T @ A
        sse, h, coef, G_out = MismatchSearch._solve(("h", A, G), b, bb)
        assert h == "h" and G_out is G
        assert np.array_equal(coef, np.linalg.lstsq(G, A.T @ b, rcond=None)[0])
        want = _explicit(A, b, coef)
        assert want / bb == pytest.approx(share, rel=0.2)
        if share >= 1e-3:
            assert sse == pytest.approx(want, rel=1e-9)
        assert abs(sse - want) <= 1e-12 * bb


def test_normal_equations_sse_of_an_exact_fit_is_not_negative():
    """b in the columns' span: rounding may make b'b - 2 c'A'b + c'G c slightly negative; the SSE is held at 0."""
    from diagnosis.search import MismatchSearch

    rng = np.random.default_rng(7)
    A = rng.normal(size=(300, 3))
    b = A @ np.array([1.0, -2.0, 0.5])
    sse = MismatchSearch._solve((0, A, A.T @ A), b, float(b @ b))[0]
    assert 0.0 <= sse <= 1e-20 * float(b @ b) + 1e-24


@pytest.fixture(scope="module")
def rd():
    from diagnosis.residual import residual_data
    from js2spec.log import read_log
    from js2spec.model import load_model

    return residual_data(load_model(clean_model()), read_log(recording(json.dumps(
        [{"kind": "payload_change", "joints": [5], "mass": 0.3, "com": [0.05, 0.0, 0.0]}]))))


def test_float_mask_sums_are_the_masked_sums(rd):
    """The gains' sums of squares per motor, from the squares and the float masks, are the sums over the masked rows
    (the einsum of x with x zeroed off the mask, as before), on every part of the rows and on one motor or all."""
    from diagnosis.search import MismatchSearch

    search = MismatchSearch()
    rows = search._row_masks(rd)
    x = np.random.default_rng(0).normal(size=(len(rd.t), rd.n))
    for motors in (np.arange(rd.n), np.array([2]), np.array([0, 4])):
        fm = search._float_masks(rd, motors)
        assert search._float_masks(rd, motors) is fm             # made once per motor set
        xs = x[:, motors]
        for name, m in rows.items():
            want = np.einsum("ij,ij->j", xs, np.where(m[:, motors], xs, 0.0))
            got = np.einsum("ij,ij->j", xs * xs, fm[name])
            np.testing.assert_allclose(got, want, rtol=1e-13, atol=0)
            direct = np.array([np.sum(xs[m[:, i], k] ** 2) for k, i in enumerate(motors)])
            np.testing.assert_allclose(got, direct, rtol=1e-12, atol=0)


def test_rigid_regressor_view_is_the_copy(rd):
    """W_rigid_motor is a view of the regressor's rigid block (no copy of it), also on a recording with bad rows
    (torque NaN on 50 samples): zeros there, and away from them the numbers of the clean recording, with the same
    rigid torque (NaN on the bad rows)."""
    from diagnosis.residual import residual_data
    from js2spec.log import read_log
    from js2spec.model import load_model

    W = rd.W_rigid_motor
    assert W.shape == (len(rd.t), rd.n, 10 * rd.n)
    assert W.base is not None and not W.flags.c_contiguous          # the view, not a copy
    assert np.all(np.isfinite(W))
    log = read_log(recording(json.dumps([{"kind": "payload_change", "joints": [5], "mass": 0.3,
                                          "com": [0.05, 0.0, 0.0]}])))
    bad = np.zeros(len(log.feedback.t), dtype=bool)
    bad[1000:1050] = True
    log.feedback.torque[bad, 2] = np.nan
    rd_bad = residual_data(load_model(clean_model()), log)
    assert rd_bad.W_rigid_motor.base is not None and not rd_bad.W_rigid_motor.flags.c_contiguous
    # the rows well after the gap (the recording splits into two runs there, each filtered on its own: the run
    # before it reads differently to its start)
    far = np.arange(len(bad)) >= 1550
    assert np.array_equal(rd_bad.W_rigid_motor[far], W[far])
    assert not np.any(rd_bad.W_rigid_motor[bad])
    assert np.array_equal(rd_bad.tau_rigid_motor[far], rd.tau_rigid_motor[far])
    assert np.all(np.isnan(rd_bad.tau_rigid_motor[bad]))


def test_lowpass_series_keep_is_the_picked_columns(rd):
    """``lowpass_series(XT, runs, keep=rows)`` is ``lowpass_series(XT, runs)[:, rows]`` to the bit: over the
    recording's runs and over ``lowpass_spans``' stretches laid end to end (as the cogging and thermal columns use
    it), with strided input; a kept sample outside every run reads 0."""
    rng = np.random.default_rng(3)
    N = len(rd.t)
    X = rng.normal(size=(11, N))
    rows = rng.random(N) < 0.4
    rows[: N // 3] = False
    assert np.array_equal(rd.lowpass_series(X, keep=rows), rd.lowpass_series(X)[:, rows])
    Xs = np.asfortranarray(X)                       # rows of XT strided
    assert np.array_equal(rd.lowpass_series(Xs, keep=rows), rd.lowpass_series(X)[:, rows])
    spans = rd.lowpass_spans(rows)
    assert spans is not None
    kept = np.concatenate([np.arange(a, b) for a, b in spans])
    ends = np.cumsum([b - a for a, b in spans])
    laid = list(zip(np.r_[0, ends[:-1]], ends))
    got = rd.lowpass_series(X[:, kept], laid, keep=rows[kept])
    assert np.array_equal(got, rd.lowpass_series(X[:, kept], laid)[:, rows[kept]])
    # a run that stops short of the end: the sample after it is kept and reads 0
    short = [(0, N - 10)]
    last = np.zeros(N, dtype=bool)
    last[[5, N - 11, N - 3]] = True
    got = rd.lowpass_series(X, short, keep=last)
    assert np.array_equal(got[:, :2], rd.lowpass_series(X[:, : N - 10], [(0, N - 10)])[:, [5, N - 11]])
    assert not np.any(got[:, 2])


@pytest.mark.parametrize("masked", [False, True])
def test_ripple_dots_are_the_columns_times_b(masked):
    """``ripple_dots`` (X^T b without the columns) against ``ripple_columns``' columns times b, with the anchors
    ``Cogging._batches`` makes (runs, gaps, more than RECUR period counts in a row) and with the speed mask or
    without, to 1e-12 of the sums' scale."""
    from diagnosis.library import Cogging
    from diagnosis.ripple_kernel import ripple_columns, ripple_dots

    rng = np.random.default_rng(11)
    L, fs = 4000, 250.0
    th = np.cumsum(rng.normal(0.0, 0.05, L)) + 40.0
    speed = np.abs(np.gradient(th) * fs)
    sliding = (rng.uniform(size=L) > 0.1).astype(float)
    forward = (rng.uniform(size=L) > 0.5).astype(float)
    fwd, bwd = forward * sliding, (1 - forward) * sliding
    b = rng.normal(size=L)
    grid = [1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 13, 14, 15, 40, 41, 96]
    (chunk, anchor, sin_a, cos_a), = list(Cogging()._batches(grid, th))
    args = (np.asarray(chunk, dtype=np.int64), anchor, sin_a, cos_a, np.sin(th), np.cos(th), fwd, bwd, speed,
            masked, float(np.pi * fs))
    X = np.empty((len(chunk), 4, L))
    ripple_columns(*args, X)
    got = np.empty((len(chunk), 4))
    ripple_dots(*args, b, got)
    want = X @ b
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-12 * np.sqrt(L))
    assert np.abs(want).max() > 1.0
    if masked:
        assert (X[-1] == 0).sum() > (X[0] == 0).sum()


def test_lowpass_adjoint_is_the_filters_transpose(rd):
    """``lowpass_adjoint`` is the transpose of ``lowpass_series``: (F X)[keep] b = X (F^T b), over the recording's
    runs with random kept rows, and on runs of 2 to 200 samples (the odd extension shorter than its full length),
    to 1e-12 of the sums' scale."""
    rng = np.random.default_rng(2)
    N = len(rd.t)
    X = rng.normal(size=(3, N))
    keep = rng.random(N) < 0.4
    b = rng.normal(size=int(keep.sum()))
    lhs = rd.lowpass_series(X, keep=keep) @ b
    np.testing.assert_allclose(X @ rd.lowpass_adjoint(b, keep=keep), lhs, rtol=0, atol=1e-12 * np.abs(lhs).max())
    whole = rng.normal(size=N)
    lhs = rd.lowpass_series(X) @ whole
    np.testing.assert_allclose(X @ rd.lowpass_adjoint(whole), lhs, rtol=0, atol=1e-12 * np.abs(lhs).max())
    for L in (2, 3, 10, 30, 80, 200):
        runs = [(0, L), (L + 5, 2 * L + 5)]
        Xs = rng.normal(size=(4, 2 * L + 10))
        kk = np.zeros(2 * L + 10, dtype=bool)
        kk[:L] = True
        kk[L + 5:2 * L + 5] = rng.random(L) < 0.7
        bb = rng.normal(size=int(kk.sum()))
        lhs = rd.lowpass_series(Xs, runs, keep=kk) @ bb
        np.testing.assert_allclose(Xs @ rd.lowpass_adjoint(bb, runs, keep=kk), lhs, rtol=0,
                                   atol=1e-12 * np.abs(lhs).max())


@pytest.mark.parametrize("kind", ["low", "wide"])
def test_cogging_gram_is_the_columns(rd, kind):
    """``Cogging.grid_gram`` (torque band) and ``CoggingWide.grid_gram`` (unfiltered): at the first call the normal
    equations the search forms from the columns (the same numbers), kept; at a later call (another residual) the
    same Gram matrices and A^T b to rounding; other rows are a new store."""
    from diagnosis.library import Cogging, CoggingWide

    term, j = (Cogging() if kind == "low" else CoggingWide()), 3
    rows = (rd.mask & part_rows(rd.fit_rows, rd.n))[:, [j]]                 # the search's fit rows on motor j
    grid = term.grid(rd, j)
    assert len(grid) > 10
    rng = np.random.default_rng(5)
    w = np.array([0.7])
    b1, b2 = rng.normal(size=(len(rd.t), 1)), rng.normal(size=(len(rd.t), 1))
    rd.extra.pop("cogging_gram", None)

    def by_columns(b):
        out = {}
        for h, X in term.grid_columns(rd, j, grid, rows):
            A = X * w[0]
            G = A.T @ A
            if np.any(np.diagonal(G)):
                out[h] = (G, A.T @ b[rows[:, 0], 0])
        return out

    first = list(term.grid_gram(rd, j, grid, rows, w, b1))
    want1 = by_columns(b1)
    assert [h for h, _, _ in first] == list(want1)
    for h, G, Ab in first:
        assert np.array_equal(G, want1[h][0]) and np.array_equal(Ab, want1[h][1])
    later = list(term.grid_gram(rd, j, grid, rows, w, b2))
    want2 = by_columns(b2)
    assert [h for h, _, _ in later] == list(want2)
    for h, G, Ab in later:
        assert np.array_equal(G, want2[h][0])
        np.testing.assert_allclose(Ab, want2[h][1], rtol=0, atol=1e-11 * np.abs(want2[h][1]).max())
    other = rows.copy()
    other[: len(other) // 2] = False
    assert len(rd.extra["cogging_gram"]) == 1
    list(term.grid_gram(rd, j, grid, other, w, b1))
    assert len(rd.extra["cogging_gram"]) == 2
    rd.extra.pop("cogging_gram", None)


def test_normal_equations_sse_of_nearly_collinear_columns_is_the_residuals():
    """Two columns equal but for 1e-7 of noise: lstsq on their Gram matrix gives coefficients of order 1e5 of
    opposite signs, whose normal-equation terms lose digits to cancellation (here 1.6e-5 of the SSE; with more
    collinearity any number, negative too). ``_solve`` then reads the SSE from the residual (stop 41: the same
    cancellation in the thermal lag's select-rows SSE chose a lag whose torque overflowed)."""
    from diagnosis.search import MismatchSearch, _cancels

    rng = np.random.default_rng(2)
    x = rng.normal(size=4000)
    A = np.column_stack([x, x + 1e-7 * rng.normal(size=4000), rng.normal(size=4000)])
    b = 0.3 * x + rng.normal(size=4000)
    G = A.T @ A
    bb = float(b @ b)
    sse, _, coef, _ = MismatchSearch._solve((0, A, G), b, bb)
    want = _explicit(A, b, coef)
    assert np.max(np.abs(coef)) > 1e4 and _cancels(coef, G, bb)
    normal = bb - 2.0 * float(coef @ (A.T @ b)) + float(coef @ G @ coef)
    assert abs(normal - want) > 1e-6 * want                 # what the normal equations alone would give
    assert sse == pytest.approx(want, rel=1e-12)
    # well-conditioned columns never take the explicit path
    A2 = rng.normal(size=(4000, 3))
    c2 = np.linalg.lstsq(A2.T @ A2, A2.T @ b, rcond=None)[0]
    assert not _cancels(c2, A2.T @ A2, bb)
