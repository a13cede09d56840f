"""Stop 42: heat is causal. A thermal drift must beat its own column with the lag run backwards in time (the heat
source filtered from the recording's end towards its start: the same level, smoothness and tie to the motion, but
a temperature that rises before the heating) on the select rows by ``ThermalDrift.shift_margin``
(``MismatchSearch._shift_check``, the null the load-dependent friction already had with its load shifted in time).
On the clean real kuka_2 recording with the kuka_3 model a 10 s "drift" on lwr_0 took 66.2 % of the motor's select
residual and its time-reversed copy 64.7 %: it was named, now it is not (docs/diagnosis.md, stop 42)."""
import numpy as np
import pytest
from scipy.signal import lfilter

from test_diag_select_choice import _drifting, _search, rd  # noqa: F401  (rd: the module's clean recording)


def _reversed_drift(rd, j: int, tau_s: float, coef: float):
    """The residuals with an anti-causal 'drift' on motor j: ThermalDrift's own null column (the lag run backwards)."""
    from diagnosis.library import ThermalDrift

    extra = np.zeros((len(rd.t), rd.n))
    extra[:, j] = coef * ThermalDrift().shifted_columns(rd, j, (tau_s, "current_squared"), "time-reversed")[:, j, 0]
    return {"low": np.nan_to_num(rd.residual) + rd.lowpass(extra), "wide": np.nan_to_num(rd.residual_wide) + extra}


def _checked(rd, res, j):
    """The thermal candidate on motor j as the ladder sees it after the nulls (``_shift_check``)."""
    from diagnosis.library import ThermalDrift

    search, weights = _search(rd, res)
    got = search._evaluate(rd, ThermalDrift(), j, res, weights)
    search.min_gain = 0.12
    search._shift_check(rd, [got], res, weights)
    return got


def test_the_null_is_the_same_column_with_the_lag_run_backwards(rd):
    """Column 0 of the null is the heat source through the lag from the end backwards (times the model's friction,
    zero at rest); the refit columns are the term's own."""
    from diagnosis.library import ThermalDrift

    term, j, h = ThermalDrift(), 1, (20.0, "current_squared")
    col, null = term.columns(rd, j, h), term.shifted_columns(rd, j, h, "time-reversed")
    np.testing.assert_array_equal(col[:, :, 1:], null[:, :, 1:])
    a = np.exp(-1.0 / (rd.fs * 20.0))
    back = lfilter([1 - a], [1, -a], term.heat_input(rd, j, "current_squared")[::-1])[::-1]
    moving = col[:, j, 1] != 0
    want = back * np.nan_to_num(rd.friction_pred[:, j])
    np.testing.assert_allclose(null[moving, j, 0], want[moving], rtol=1e-12, atol=1e-15)
    # the two differ: early in the session the causal column is near zero (cold), the backward one is not
    early = rd.t - rd.t[0] < 2.0
    assert np.abs(col[early & moving, j, 0]).max() < 0.3 * np.abs(null[early & moving, j, 0]).max()


def test_a_causal_drift_beats_its_time_reversed_copy(rd):
    """A drift of a lag about the recording's span, added to the clean recording's residual, is named plausible:
    its backward copy leaves more on the select rows than the margin asks."""
    j = 0
    got = _checked(rd, _drifting(rd, j, 0.8 * float(rd.t[-1] - rd.t[0]), 1.0), j)
    assert got.fitted.plausible, got.fitted.why_not
    assert got.select_gain > 0.5


def test_an_anti_causal_drift_is_refused(rd):
    """A friction change that follows the heat source backwards in time (a temperature rising before the heating)
    is no thermal drift: the causal lag fitted to it does not beat the null, and the reason says so. (A backward lag
    of about the recording's span reads as a ramp, refused at the slowest lag anyway: a fifth of it, 8 s, here.)"""
    j = 0
    got = _checked(rd, _reversed_drift(rd, j, 0.2 * float(rd.t[-1] - rd.t[0]), 1.0), j)
    assert not got.fitted.plausible and got.select_gain > 0.12        # it passes the floor: the null refuses it
    assert "lag run backwards in time" in got.fitted.why_not and "warming that follows the heat" in got.fitted.why_not


def test_the_load_dependent_friction_keeps_its_wording():
    """Both nulls go through one check; each term says what its null is and what its gain would come from."""
    from diagnosis.library import LoadDependentFriction, ThermalDrift

    assert LoadDependentFriction.shift_null == "its own column shifted in time"
    assert LoadDependentFriction.shift_claim == "the tie to the load"
    assert ThermalDrift.shift_lags == ("time-reversed",) and ThermalDrift.shift_margin == pytest.approx(0.10)
