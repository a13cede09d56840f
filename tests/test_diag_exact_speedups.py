"""The compiled link simulation (``diagnosis.link_kernel.link_torques``) gives the numbers of the vectorised numpy
loop it replaced, to the bit: on random inputs where every lane resolves its pieces (the trapezoidal branch), where
tiny inertias do not (the per-lane theta branch), on a lane that diverges, and through ``_link_responses`` on a
simulated recording."""
import json

import numpy as np
import pytest

from fixtures_diag import clean_model, recording


def reference_link_torques(hm_joint, tau_r, gp_joint, owner, half, k, d, h, n_sub, delta0):
    """The numpy loop of stop 33 (``_link_responses`` before the kernel): lanes as vectors, samples in Python."""
    N, L = hm_joint.shape[0], len(owner)
    neg_half, k_half, h_half = -half, k * half, h * 0.5
    delta, ddelta = delta0.copy(), np.zeros(L)
    out = np.empty((N, L))
    hm_b, tr_b, gp_b = hm_joint[:, owner], tau_r[:, owner], gp_joint[:, owner]
    resolved = np.all((hm_b * (d + h * np.abs(k + gp_b)) < 1.0) & (hm_b * (h * np.abs(gp_b)) < 1.0), axis=1)
    states = np.empty((N, 2, L))

    def piece(delta, ddelta, gp, tr):          # the contact's piece: +1, -1 in contact, 0 in the gap
        side = np.subtract(delta > half, delta < neg_half, dtype=float)
        touch = np.abs(side)
        stiff = k * touch + gp
        damp = d * touch
        force = k_half * side - tr
        return stiff, damp, force, force - stiff * delta - damp * ddelta

    for i in range(N):
        hm, tr, gp = hm_b[i], tr_b[i], gp_b[i]
        if resolved[i]:
            hm2 = hm * 0.5
            for _ in range(n_sub):
                stiff, damp, force, f0 = piece(delta, ddelta, gp, tr)
                tmp = (force - (h_half * ddelta + delta) * stiff + f0) * hm2 + ddelta
                den = (h_half * stiff + damp) * hm2 + 1.0
                v1 = tmp / den
                delta = delta + (ddelta + v1) * h_half
                ddelta = v1
        else:
            for _ in range(n_sub):
                stiff, damp, force, f0 = piece(delta, ddelta, gp, tr)
                th = np.where(hm * (damp + h * np.abs(stiff)) < 1.0, 0.5, 1.0)
                one_minus_th = 1 - th
                v_new = (ddelta + hm * (one_minus_th * f0 + th * (force - stiff * (delta + h * one_minus_th * ddelta)))) \
                    / np.maximum(1.0 + hm * th * (damp + h * th * stiff), 0.25)
                delta = delta + h * (one_minus_th * ddelta + th * v_new)
                ddelta = v_new
        states[i, 0], states[i, 1] = delta, ddelta
    dl, dd = states[:, 0], states[:, 1]
    excess = dl - np.clip(dl, -half, half)
    out[:] = -k * excess - d * dd * (excess != 0) - tr_b
    return out


def _inputs(seed, N=400, n=3, tiny=False):
    rng = np.random.default_rng(seed)
    M = rng.uniform(0.02, 2.0, (N, n))
    if tiny:
        M[rng.random((N, n)) < 0.2] = 1e-7           # inertias the sub-step does not resolve
    t = np.arange(N) / 500.0
    tau_r = np.sin(2 * np.pi * 1.3 * t)[:, None] * rng.uniform(0.5, 20, n) + rng.normal(0, 0.3, (N, n))
    gp = rng.normal(0, 5.0, (N, n))
    owner = np.repeat(np.arange(n), 8)
    half = rng.uniform(0.0025, 0.04, len(owner))
    m_typ = np.median(M, axis=0)[owner]
    f = rng.choice([3.0, 6.0, 12.0, 24.0], len(owner))
    k = m_typ * (2 * np.pi * f) ** 2
    d = 2 * rng.choice([0.05, 0.3], len(owner)) * m_typ * 2 * np.pi * f
    h = 1 / 500 / 2
    delta0 = -tau_r[0, owner] / k - np.sign(tau_r[0, owner]) * half
    return h / M, tau_r, gp, owner, half, k, d, h, 2, delta0


@pytest.mark.parametrize("tiny", [False, True])
def test_kernel_is_the_numpy_loop_to_the_bit(tiny):
    from diagnosis.link_kernel import link_torques

    args = _inputs(7, tiny=tiny)
    got = link_torques(*args)
    want = reference_link_torques(*args)
    assert got.shape == want.shape
    fin = np.isfinite(want)
    assert fin.mean() > 0.9                          # the comparison is on numbers, not on NaNs
    assert np.array_equal(np.isfinite(got), fin)
    assert np.array_equal(got[fin], want[fin])       # bit for bit, not close
    if tiny:                                         # the per-lane theta branch really ran
        hm, _, gp, owner, _, k, d, h, _, _ = args
        resolved = np.all((hm[:, owner] * (d + h * np.abs(k + gp[:, owner])) < 1.0), axis=1)
        assert not resolved.all()


def test_responses_of_a_recording_are_the_numpy_loops():
    """Through ``_link_responses`` on a simulated recording (the search's real inputs)."""
    from diagnosis import library
    from diagnosis.residual import residual_data
    from js2spec.log import read_log
    from js2spec.model import load_model

    rd = residual_data(load_model(clean_model()), read_log(recording(json.dumps(
        [{"kind": "payload_change", "joints": [5], "mass": 0.3, "com": [0.05, 0.0, 0.0]},
         {"kind": "stribeck", "joints": [1], "velocity": 4.0}]))))
    got = library._link_responses(rd)
    n = rd.n
    M = np.stack([np.clip(np.nan_to_num(library._mass_column(rd, j)[:, j]), 1e-9, None) for j in range(n)], axis=1)
    Gp = np.stack([np.nan_to_num(library._rnea_dq(rd, j)[:, j]) for j in range(n)], axis=1)
    tau_r = np.nan_to_num(rd.tau_rigid_joint)
    owner = np.repeat(np.arange(n), [len(got[j][1]) for j in range(n)])
    grid = [g for j in range(n) for g in got[j][1]]
    half = np.array([g[0] / 2 for g in grid])
    k = np.array([g[1] for g in grid])
    d = np.array([g[2] for g in grid])
    dt = 1.0 / rd.fs
    n_sub = int(np.clip(np.ceil(2 * np.pi * max(library.NATURAL_HZ) * dt / 0.25), 1, 16))
    h = dt / n_sub
    delta0 = -tau_r[0, owner] / k - np.sign(tau_r[0, owner]) * half
    want = reference_link_torques(h / M, tau_r, Gp, owner, half, k, d, h, n_sub, delta0)
    for j in range(n):
        w = want[:, owner == j]
        w[:, ~np.all(np.isfinite(w), axis=0)] = 0.0
        assert np.array_equal(got[j][0], w), j


@pytest.mark.parametrize("rows", [1, 5, 19])
@pytest.mark.parametrize("length,padlen", [(5000, 60), (61, 60), (40, 39), (2, 1), (1, 0)])
def test_filtfilt_rows_is_scipys_sosfiltfilt_to_the_bit(length, padlen, rows):
    """``diagnosis.residual.filtfilt_rows`` (the filter's initial state made once, the compiled loop 8 series at a
    time: 19 rows are two full blocks and a partial one) against scipy's own."""
    from scipy.signal import butter, sosfilt_zi, sosfiltfilt

    from diagnosis.residual import filtfilt_rows

    sos = butter(4, 7.0, fs=500.0, output="sos")
    x = np.random.default_rng(length).normal(size=(rows, length)).cumsum(axis=1)
    zi = sosfilt_zi(sos).reshape(len(sos), 1, 2)
    assert np.array_equal(filtfilt_rows(sos, zi, x, padlen), sosfiltfilt(sos, x, axis=-1, padlen=padlen))
    # a view with strides (every other sample), as the search passes slices of its batches
    xs = np.random.default_rng(length + 1).normal(size=(rows, 2 * length)).cumsum(axis=1)[:, ::2]
    assert np.array_equal(filtfilt_rows(sos, zi, xs, padlen), sosfiltfilt(sos, xs, axis=-1, padlen=padlen))


def _ripple_columns_numpy(chunk, th, fwd, bwd, speed, masked, fs, recur=8):
    """The numpy steps diagnosis.ripple_kernel replaced (Cogging.grid_columns until stop 39), as they were."""
    s1, c1 = np.sin(th), np.cos(th)
    XT = np.empty((len(chunk), 4, len(th)))
    prev = None
    fwd_all, bwd_all = fwd, bwd
    for i, h in enumerate(chunk):
        if prev is not None and h == prev[0] + 1 and i % recur:
            s = prev[1] * c1 + prev[2] * s1
            c = prev[2] * c1 - prev[1] * s1
        else:
            s, c = np.sin(h * th), np.cos(h * th)
        prev = (h, s, c)
        if masked:
            under = (speed * h <= np.pi * fs).astype(float)
            fwd, bwd = fwd_all * under, bwd_all * under
        np.multiply(s, fwd, out=XT[i, 0])
        np.multiply(c, fwd, out=XT[i, 1])
        np.multiply(s, bwd, out=XT[i, 2])
        np.multiply(c, bwd, out=XT[i, 3])
    return XT


@pytest.mark.parametrize("masked", [False, True])
def test_ripple_columns_are_the_numpy_steps_to_the_bit(masked):
    """diagnosis.ripple_kernel.ripple_columns, with the anchors Cogging.grid_columns computes (the batch's start,
    every RECUR period counts, after a gap in the grid), against the numpy steps it replaced."""
    from diagnosis.library import Cogging
    from diagnosis.ripple_kernel import ripple_columns

    rng = np.random.default_rng(7)
    L, fs = 3000, 250.0
    th = np.cumsum(rng.normal(0.0, 0.05, L)) + 40.0            # a motor angle far from 0 (large p theta)
    w = np.gradient(th) * fs
    sliding = (rng.uniform(size=L) > 0.1).astype(float)
    fwd = (w >= 0).astype(float) * sliding
    bwd = (1 - (w >= 0).astype(float)) * sliding
    speed = np.abs(w)
    chunk = [1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 13, 14, 15, 40, 41, 96]     # runs, gaps, more than RECUR in a row
    want = _ripple_columns_numpy(chunk, th, fwd, bwd, speed, masked, fs, Cogging.RECUR)
    fresh = [i for i, h in enumerate(chunk) if i % Cogging.RECUR == 0 or h != chunk[i - 1] + 1]
    anchor = np.full(len(chunk), -1, dtype=np.int64)
    anchor[fresh] = np.arange(len(fresh))
    got = np.empty_like(want)
    ripple_columns(np.asarray(chunk, dtype=np.int64), anchor, np.stack([np.sin(chunk[i] * th) for i in fresh]),
                   np.stack([np.cos(chunk[i] * th) for i in fresh]), np.sin(th), np.cos(th), fwd, bwd, speed,
                   masked, float(np.pi * fs), got)
    assert np.array_equal(got, want)
    if masked:      # the mask bites: some rows of the fine ripples are zeroed, not of the coarse ones
        assert (got[-1] == 0).sum() > (got[0] == 0).sum()
