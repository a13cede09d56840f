"""Stop 41: a thermal drift's time constant is chosen on the SELECT rows (``Term.hyper_on_select``,
``MismatchSearch._fit_grid_on``): at every lag of the grid the coefficients come from the FIT rows, as for any term,
and the lag kept is the one whose coefficients leave the least (weighted) residual on the SELECT rows. The fit rows
(the excitation) often hold too little of the heating's course to tell a lag of the recording's span from a ramp;
the select rows (the validation trial, later in the session) see whether the friction levels off."""
import json

import numpy as np
import pytest

from diagnosis.residual import part_rows
from fixtures_diag import clean_model, recording


@pytest.fixture(scope="module")
def rd():
    from diagnosis.residual import residual_data
    from js2spec.log import read_log
    from js2spec.model import load_model

    return residual_data(load_model(clean_model()), read_log(recording(json.dumps([]))))


def _search(rd, res):
    """A search set up as ``MismatchSearch.fit`` sets it up before its ladder, on the residuals ``res``."""
    from diagnosis.search import MismatchSearch, _rms

    search = MismatchSearch()
    m_fit = rd.mask & part_rows(rd.fit_rows, rd.n)
    weights = {}
    for band, r in res.items():
        rms = _rms(r, m_fit)
        weights[band] = 1.0 / np.where(np.isfinite(rms) & (rms > 0), rms, 1.0)
    search._fits, search._stats_cache, search._masks = {}, {}, None
    search._columns_cache, search._cache_used, search._stores, search._block_parts = {}, 0, set(), {}
    search._versions = {band: np.zeros(rd.n, dtype=int) for band in res}
    return search, weights


def _drifting(rd, j: int, tau_s: float, coef: float):
    """The recording's residuals with a thermal drift added on motor j: ``coef`` times ThermalDrift's own heat column
    (the winding's I^2 through a lag of ``tau_s``, times the model's friction), in the torque band."""
    from diagnosis.library import ThermalDrift

    term = ThermalDrift()
    drift = np.zeros((len(rd.t), rd.n))
    drift[:, j] = coef * term.columns(rd, j, (tau_s, "current_squared"))[:, j, 0]    # zero where the motor rests
    low = rd.lowpass(drift)
    return {"low": np.nan_to_num(rd.residual) + low, "wide": np.nan_to_num(rd.residual_wide) + drift}


def _brute_force(rd, term, j, res, weights):
    """Every grid point's select-rows SSE of its fit-rows least squares, column by column (no store, no shortcuts)."""
    from diagnosis.search import MismatchSearch

    rows = MismatchSearch()._row_masks(rd)
    fit, sel = rows["fit_rows"][:, j], rows["select_rows"][:, j]
    w = weights["low"][j]
    b = res["low"][:, j] * w
    out = []
    for h in term.grid(rd, j):
        X = term.band_columns(rd, j, h)[:, j, :] * w
        coef = np.linalg.lstsq(X[fit], b[fit], rcond=None)[0]
        out.append((float(np.sum((b[sel] - X[sel] @ coef) ** 2)), float(np.sum((b[fit] - X[fit] @ coef) ** 2)), h))
    return out


def test_the_lag_kept_is_the_one_the_select_rows_prefer(rd):
    """With a drift of a lag about the recording's span on motor 1, the search's candidate is the grid point whose
    fit-rows coefficients leave the least on the select rows (computed here column by column), that point is the
    grid's nearest to the true lag, and the coefficients are the fit rows' at that point."""
    from diagnosis.library import ThermalDrift

    span = float(rd.t[-1] - rd.t[0])
    assert rd.fit_rows.any() and rd.select_rows.any()
    assert rd.t[rd.select_rows.any(axis=1)].min() > rd.t[rd.fit_rows.any(axis=1)].max()   # validation comes after
    tau = 0.8 * span
    term, j = ThermalDrift(), 0
    res = _drifting(rd, j, tau, 1.0)          # 0.39 A^2 in the winding: the friction rises by 25 % over the session
    search, weights = _search(rd, res)
    got = search._evaluate(rd, term, j, res, weights)
    brute = _brute_force(rd, term, j, res, weights)
    best_select, best_fit = min(brute, key=lambda x: x[0]), min(brute, key=lambda x: x[1])
    assert got.fitted.hyper == best_select[2]
    assert best_fit[2] != best_select[2]           # here the two choices differ: the select rows' is the one kept
    step = np.log(term.grid(rd, j)[1][0] / term.grid(rd, j)[0][0])
    assert got.fitted.hyper[1] == "current_squared" and abs(np.log(got.fitted.hyper[0] / tau)) < 1.01 * step
    assert got.fitted.coef[0] == pytest.approx(1.0, rel=0.25)
    assert got.fitted.plausible and got.select_gain > 0.5


@pytest.mark.parametrize("blocks", [True, False])
def test_the_choice_is_the_fit_rows_least_squares_at_every_point(rd, blocks):
    """``_fit_grid_on`` agrees with the column-by-column reading at every grid point (select SSE to 1e-8 relative),
    and the std it reports come from the chosen point's fit-rows SSE; both ways: from the blocks' dot products
    (``_fit_grid_blocks``, the thermal drift's) and from each grid point's columns (any other term)."""
    from diagnosis.library import ThermalDrift

    term = ThermalDrift() if blocks else type("ThermalColumns", (ThermalDrift,), {"grid_blocks": False})()
    j = 2
    res = _drifting(rd, j, 30.0, 0.05)
    search, weights = _search(rd, res)
    brute = {h: (s, f) for s, f, h in _brute_force(rd, term, j, res, weights)}
    rows = search._row_masks(rd)
    motors = term.motors(rd, j)
    rw = res["low"] * weights["low"]
    for h, (sel_sse, fit_sse) in list(brute.items())[::7]:
        # a one-point grid: the point itself; its std comes from the fit rows' SSE
        hh, coef, std, _ = search._fit_grid_on(rd, term, j, motors, rows["fit_rows"][:, motors],
                                               rows["select_rows"][:, motors], rw, weights["low"], [h, h])
        assert hh == h
        X = term.band_columns(rd, j, h)[:, j, :] * weights["low"][j]
        sel = rows["select_rows"][:, j]
        assert float(np.sum((rw[sel, j] - X[sel] @ coef) ** 2)) == pytest.approx(sel_sse, rel=1e-8)
        fit = rows["fit_rows"][:, j]
        G = X[fit].T @ X[fit]
        want_std = np.sqrt(np.diag(fit_sse / (int(fit.sum()) - 3) * np.linalg.pinv(G)))
        np.testing.assert_allclose(std, want_std, rtol=1e-6)
    s, f, h = min(((s, f, h) for h, (s, f) in brute.items()), key=lambda x: x[0])
    for key in (None, (term, j), (term, j)):           # no store, then one made and one read
        hh, coef, std, _ = search._fit_grid_on(rd, term, j, motors, rows["fit_rows"][:, motors],
                                               rows["select_rows"][:, motors], rw, weights["low"], list(brute), key)
        assert hh == h
    assert (key in search._block_parts) == blocks


def test_without_select_rows_on_its_motor_the_fit_rows_choose(rd):
    """Where the term's motor has fewer than 20 select rows (all of them lost, say), the lag is the fit rows' choice
    as before stop 41, not the first of a grid of equal (empty) select sums."""
    import copy

    from diagnosis.library import ThermalDrift

    bare = copy.copy(rd)
    bare.select_rows = np.zeros_like(rd.select_rows)
    bare.extra = {}
    term, j = ThermalDrift(), 0
    res = _drifting(bare, j, 0.8 * float(rd.t[-1] - rd.t[0]), 1.0)
    search, weights = _search(bare, res)
    got = search._evaluate(bare, term, j, res, weights)
    brute = _brute_force(bare, term, j, res, weights)
    assert got.fitted.hyper == min(brute, key=lambda x: x[1])[2] != term.grid(bare, j)[0]


def test_only_the_thermal_drift_chooses_on_the_select_rows():
    """The other terms keep the fit rows' choice (their hyper-parameters are shapes the fit rows resolve); the
    choice on select rows is the thermal drift's alone."""
    from diagnosis.library import LIBRARY, ThermalDrift

    assert {type(t) for t in LIBRARY if t.hyper_on_select} == {ThermalDrift}


def test_a_term_is_not_fitted_on_fewer_independent_samples_of_its_motor_than_the_floor(rd):
    """``MismatchSearch.MIN_FIT_SAMPLES``: a term named on joint j needs 2 f_c T >= 20 independent samples of its
    motor's fit rows (the torque band's f_c, T their duration); a payload counts every motor's. A motor left with
    0.5 s of fit rows (7 independent samples at 7 Hz) gets no friction term and no play, though a play's columns
    reach every motor; the other motors, and a payload on the hand whose motor is the short one, are fitted."""
    import copy

    from diagnosis.library import Backlash, FrictionRefit, PayloadChange
    from diagnosis.search import MismatchSearch

    res = {"low": np.nan_to_num(rd.residual), "wide": np.nan_to_num(rd.residual_wide)}
    per_sample = MismatchSearch._rows_per_sample(rd)
    assert per_sample == pytest.approx(rd.fs / (2 * rd.signals.settings.fc_acceleration_hz))
    keep_rows = int(0.5 * rd.fs)
    assert keep_rows < 20 * per_sample

    def short_on(j):
        short = copy.copy(rd)
        short.extra = {"model": rd.extra["model"], "min_speed": rd.extra["min_speed"]}
        fit = part_rows(rd.fit_rows, rd.n).copy()
        on = np.flatnonzero(fit[:, j] & rd.mask[:, j])
        assert len(on) > 10 * keep_rows
        fit[on[keep_rows:], j] = False
        short.fit_rows = fit
        return short, *_search(short, res)

    short, search, weights = short_on(0)
    assert search._evaluate(short, FrictionRefit(), 0, res, weights) is None
    assert search._evaluate(short, Backlash(), 0, res, weights) is None
    assert search._evaluate(short, FrictionRefit(), 1, res, weights) is not None
    full, w_full = _search(rd, res)
    assert full._evaluate(rd, FrictionRefit(), 0, res, w_full) is not None
    assert full._evaluate(rd, Backlash(), 0, res, w_full) is not None
    hand = rd.n - 1
    short, search, weights = short_on(hand)
    assert search._evaluate(short, FrictionRefit(), hand, res, weights) is None
    assert search._evaluate(short, PayloadChange(), hand, res, weights) is not None
