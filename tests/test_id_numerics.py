"""Identification numerics without the simulator: regressor (eq. 1) vs pinocchio RNEA, base parameters, filters and
lost cycles, RLS vs filterpy's Kalman filter, OLS standard errors, sequential-test estimators, consistency."""
from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from identification.base import base_parameters, condition_number
from identification.consistency import (PhysicalConsistencyFit, is_physical, logchol_to_pseudo, params_from_pseudo,
                                        pseudo_from_params, pseudo_to_logchol)
from identification.estimators import BatchLeastSquares, RecursiveLeastSquares
from identification.regressor import arm_model, build_regressor, column_groups, standard_names, standard_vector
from identification.sequential import Breakaway, StaticFrictionTest, _line_fit
from identification.signals import FilterSettings, process
from js2spec.errors import ConfigError
from js2spec.robot import load_robot


@pytest.fixture(scope="module")
def js2():
    r = load_robot("js2")
    return r, arm_model(r.urdf_text, r.drives)


def _random_motion(arm, N, seed):
    rng = np.random.default_rng(seed)
    qj = rng.uniform(-2, 2, size=(N, arm.n))
    Kinv = arm.Kinv
    return ((qj - arm.joint_offset) @ Kinv.T, rng.normal(size=(N, arm.n)) * 80, rng.normal(size=(N, arm.n)) * 500)


def test_regressor_matches_rnea_and_motor_terms_with_coupled_wrist(js2):
    """tau_m = K^T RNEA(theta, K dq_m, K ddq_m) + J_a ddq_m + B dq_m + f_c sgn(dq_m)  (eq. 1), K coupled."""
    robot, arm = js2
    K = arm.K
    assert not np.allclose(K, np.diag(np.diag(K))), "the Js-2 wrist must be coupled for this test to mean anything"
    qm, dqm, ddqm = _random_motion(arm, 40, 1)
    Ja, B, fc = np.r_[1, 2, 3, 4, 5, 6] * 1e-6, np.r_[6, 5, 4, 3, 2, 1] * 1e-5, np.r_[1, 3, 2, 5, 4, 6] * 1e-3
    pi = standard_vector(arm, motor_inertia=Ja, viscous=B, coulomb=fc)
    tau = build_regressor(arm, qm, dqm, ddqm) @ pi
    model = pin.buildModelFromXML(robot.urdf_text)
    data = model.createData()
    for s in range(len(qm)):
        q = K @ qm[s] + arm.joint_offset
        tj = pin.rnea(model, data, q, K @ dqm[s], K @ ddqm[s])
        expect = K.T @ tj + Ja * ddqm[s] + B * dqm[s] + fc * np.sign(dqm[s])
        np.testing.assert_allclose(tau[s], expect, rtol=1e-10, atol=1e-14)


def test_base_parameters_reproduce_torques_and_name_regroupings(js2):
    _, arm = js2
    bp = base_parameters(arm)
    qm, dqm, ddqm = _random_motion(arm, 60, 2)
    W = build_regressor(arm, qm, dqm, ddqm)
    rng = np.random.default_rng(3)
    pi = rng.normal(size=W.shape[-1])
    np.testing.assert_allclose(bp.project(W) @ bp.beta(pi), W @ pi, rtol=1e-8, atol=1e-10)
    # the base regressor has full column rank, the standard one does not
    Wb = bp.project(W).reshape(-1, bp.n)
    assert np.linalg.matrix_rank(Wb) == bp.n < W.shape[-1]
    assert np.isfinite(condition_number(bp.project(W)))
    # the names spell the combinations: each base parameter's name starts with its lead
    for i in range(bp.n):
        assert bp.names[i].split(" ")[0] == bp.lead(i)
    # a motor inertia regrouped with link inertias: its column is a combination of the others'
    g = column_groups(arm)
    for k in range(arm.n):
        name = f"Ja_{k + 1}"
        col = W[..., g["motor"][k]].reshape(-1)
        others = np.delete(W.reshape(-1, W.shape[-1]), g["motor"][k], axis=1)
        resid = col - others @ np.linalg.lstsq(others, col, rcond=None)[0]
        separable = np.linalg.norm(resid) > 1e-6 * np.linalg.norm(col)
        assert bp.is_alone(name) == separable, name


def test_urdf_joints_not_matching_drives_is_a_config_error(js2):
    robot, _ = js2
    urdf = robot.urdf_text.replace('name="j3"', 'name="elbow"')
    with pytest.raises(ConfigError, match="do not match drives.yaml joints"):
        arm_model(urdf, robot.drives, urdf_name="x.urdf")


def test_filters_differentiate_zero_phase_and_handle_lost_cycles():
    fs = 500.0
    t = np.arange(4000) / fs
    f = 1.3
    q = np.column_stack([np.sin(2 * np.pi * f * t), 0.5 * np.cos(2 * np.pi * f * t)])
    tau = q.copy()
    cycle = np.arange(len(t))
    keep = np.ones(len(t), dtype=bool)
    keep[1500:1503] = False           # short gap: bridged for the filter only
    keep[2500:2600] = False           # long gap: splits the record
    sig = process(t[keep], cycle[keep], q[keep], tau[keep], None, fs, FilterSettings())
    w = 2 * np.pi * f
    good = sig.keep
    assert good.sum() > 2500
    dq_true = np.column_stack([w * np.cos(w * t), -0.5 * w * np.sin(w * t)])
    ddq_true = -w * w * q
    np.testing.assert_allclose(sig.dq_motor[good], dq_true[good], atol=2e-3 * w)
    np.testing.assert_allclose(sig.ddq_motor[good], ddq_true[good], atol=2e-2 * w * w)   # 7 Hz Butterworth at 1.3 Hz
    np.testing.assert_allclose(sig.tau[good], tau[good], atol=2e-2)                        # zero phase: no lag
    # no missing or bridged sample (nor its guard band) is used
    assert not good[1500:1503].any() and not good[2500:2600].any()
    assert not good[1500 - 50:1503 + 50].any()
    assert len(sig.runs) == 2 and sig.n_lost == 103
    assert "bridged for filtering only" in sig.note and "split into 2 runs" in sig.note


def _kf_rls(H, y, P0):
    from filterpy.kalman import KalmanFilter

    N, m, p = H.shape
    kf = KalmanFilter(dim_x=p, dim_z=m)
    kf.x = np.zeros(p)
    kf.P = P0.copy()
    kf.R = np.eye(m)
    kf.Q = np.zeros((p, p))
    kf.F = np.eye(p)
    xs = []
    for s in range(N):
        kf.H = H[s]
        kf.update(y[s])
        xs.append(kf.x.copy())
    return np.array(xs), kf.P


def test_rls_block_equals_recursion_equals_filterpy_kalman():
    rng = np.random.default_rng(7)
    N, m, p = 400, 3, 6
    H = rng.normal(size=(N, m, p)) * np.array([1, 30, 0.05, 2, 300, 0.5])
    theta = rng.normal(size=p)
    y = H @ theta + 0.02 * rng.normal(size=(N, m))
    blk = RecursiveLeastSquares(n_iter=None, method="block", n_checkpoints=40).fit(H, y)
    rec = RecursiveLeastSquares(n_iter=None, method="recursive", n_checkpoints=40).fit(H, y)
    P0, _ = blk._prior(H, np.ones_like(y))
    xs, P = _kf_rls(H, y, P0)
    np.testing.assert_array_equal(blk.history_iter_, rec.history_iter_)
    kf_hist = xs[blk.history_iter_ - 1]
    scale = np.abs(theta)
    np.testing.assert_allclose(blk.history_[5:] / scale, kf_hist[5:] / scale, atol=1e-7)
    np.testing.assert_allclose(rec.history_ / scale, kf_hist / scale, atol=1e-7)
    np.testing.assert_allclose(blk.coef_, xs[-1], rtol=1e-9)
    np.testing.assert_allclose(blk.cov_, P, rtol=1e-6, atol=1e-14)
    # n_iter: only the first iterations are used
    short = RecursiveLeastSquares(n_iter=100, P0=P0).fit(H, y)
    np.testing.assert_allclose(short.coef_, xs[99], rtol=1e-7)


def test_ols_wls_standard_errors_are_calibrated():
    """Across noise realisations the estimates scatter as the reported standard errors say."""
    rng = np.random.default_rng(11)
    N, m, p = 300, 2, 4
    H = rng.normal(size=(N, m, p))
    theta = np.array([1.0, -2.0, 0.5, 3.0])
    sig = np.array([0.1, 0.4])           # per-row noise: WLS should weight it
    est, sds, est_w = [], [], []
    for k in range(150):
        y = H @ theta + sig * rng.normal(size=(N, m))
        o = BatchLeastSquares("ols").fit(H, y)
        w = BatchLeastSquares("wls").fit(H, y)
        est.append(o.coef_), sds.append(o.std_), est_w.append(w.coef_)
    est, sds, est_w = map(np.array, (est, sds, est_w))
    ratio = est.std(axis=0) / sds.mean(axis=0)
    assert np.all((ratio > 0.75) & (ratio < 1.3)), ratio
    assert np.all(est_w.std(axis=0) < est.std(axis=0))       # WLS beats OLS with unequal row noise


def test_static_test_eq3_eq4_and_eq5_line():
    recs = []
    fs_true, g = [0.03, 0.01], {(0.0,): 0.05, (0.5,): -0.02}
    for m in range(2):
        for pose, G in g.items():
            recs.append(Breakaway(m, 1, G + fs_true[m], pose))
            recs.append(Breakaway(m, -1, G - fs_true[m], pose))
    st = StaticFrictionTest(3).fit(recs)
    np.testing.assert_allclose(st.static_[:2], fs_true)
    assert np.isnan(st.static_[2])                               # untested axis: NaN, not 0
    grav = {(e["motor"], tuple(e["pose"])): e["torque"] for e in st.gravity_}
    assert grav[(0, (0.5,))] == pytest.approx(-0.02)
    x = np.array([-80, -40, -10, 10, 40, 80.0])
    y = 2e-4 * x + 0.02 * np.sign(x) + np.array([1, -1, 1, -1, 1, -1]) * 1e-5
    B, fc, sB, sfc = _line_fit(x, y)
    assert B == pytest.approx(2e-4, rel=1e-2) and fc == pytest.approx(0.02, rel=1e-2)
    assert 0 < sB < 1e-5 and 0 < sfc < 1e-4


def test_log_cholesky_is_physical_and_consistent_fit_recovers_feasible_truth(js2):
    _, arm = js2
    rng = np.random.default_rng(5)
    for _ in range(20):
        J = logchol_to_pseudo(rng.normal(size=10))
        p10 = params_from_pseudo(J)
        assert is_physical(p10, tol=1e-12)
        np.testing.assert_allclose(pseudo_from_params(p10), J, atol=1e-12)
        np.testing.assert_allclose(logchol_to_pseudo(pseudo_to_logchol(J)), J, atol=1e-9)
    # base parameters of a physical truth: the fit finds physical links with the same base parameters
    bp = base_parameters(arm)
    truth = standard_vector(arm, motor_inertia=np.full(6, 1e-5), viscous=np.full(6, 1e-4), coulomb=np.full(6, 0.01))
    beta = bp.beta(truth)
    qm, dqm, ddqm = _random_motion(arm, 300, 9)
    Wb = bp.project(build_regressor(arm, qm, dqm, ddqm)).reshape(-1, bp.n)
    gram = Wb.T @ Wb / 1e-8
    p = len(bp.std_names)
    g = column_groups(arm)
    fixed = np.full(p, np.nan)
    fixed[np.r_[g["viscous"], g["coulomb"]]] = truth[np.r_[g["viscous"], g["coulomb"]]]
    nominal = arm.nominal_inertial * rng.uniform(0.7, 1.3, size=arm.nominal_inertial.shape)  # a wrong prior
    fit = PhysicalConsistencyFit(max_nfev=300).fit(bp.E, beta, gram, nominal, arm.n, g["motor"], fixed)
    assert fit.physical_.all()
    tau_true = Wb @ beta
    tau_fit = Wb @ fit.beta_
    assert np.sqrt(np.mean((tau_fit - tau_true) ** 2)) < 1e-3 * np.sqrt(np.mean(tau_true ** 2))
    assert standard_names(arm)[-1] == "fc_6"


def test_false_breakaways_are_left_out_of_eq3():
    """A ramp whose axis moves against the ramp (it was sliding, not at rest) or a pose with tau+ <= tau- measures
    no breakaway: it is rejected with the reason instead of corrupting f_s."""
    from identification.trials import _check_direction
    from js2spec.log import FeedbackArrays

    t = np.arange(200) / 500.0
    pos = np.zeros((200, 1))
    pos[100:, 0] = -0.01 * np.arange(100)           # the motor slides negative from t = 0.2 s
    fb = FeedbackArrays(cycle=np.arange(200), t=t, motor_position=pos, torque=np.zeros((200, 1)),
                        motor_current=None, status=None, valid=np.ones((200, 1), bool))
    assert "against the ramp" in _check_direction(fb, 0, +1, 0.0, 0.21, 4096)
    assert _check_direction(fb, 0, -1, 0.0, 0.21, 4096) == ""
    # what happens after the breakaway (the trial backs off) does not count
    assert _check_direction(fb, 0, +1, 0.0, 0.19, 4096) == ""
    recs = [Breakaway(0, 1, 0.05, (0.0,)), Breakaway(0, -1, -0.01, (0.0,)),        # good: f_s = 0.03
            Breakaway(0, 1, -0.02, (1.0,)), Breakaway(0, -1, -0.01, (1.0,)),       # tau+ < tau-: rejected
            Breakaway(0, 1, 0.5, (2.0,), rejected="axis moved against the ramp"), Breakaway(0, -1, 0.0, (2.0,))]
    st = StaticFrictionTest(1).fit(recs)
    assert st.static_[0] == pytest.approx(0.03) and st.pairs_[0] == 1
    assert len(st.rejected_) == 2
