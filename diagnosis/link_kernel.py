"""The inner loop of the link-behind-a-gear simulation (:func:`diagnosis.library._link_responses`), compiled.

Every lane (one joint's link on one spring of the grid) steps through the recording on its own, so the loop is a
sample loop around a lane loop around a sub-step loop. In numpy the sample loop stays in Python (~28 ufunc calls per
sub-step on 240 lanes: 7 CPU s of a 5-minute, 500 Hz session). Compiled by numba (``njit``, cached on disk beside
this file after the first run) the same loop is one pass over the arrays. Each lane does the same IEEE operations,
in the same order, as the vectorised form did (numba's default: no fast-math, no fused multiply-add), so the numbers
are the same to the bit; ``tests/test_diag_exact_speedups.py`` holds a numpy reference of the loop and checks it.

Array in, array out, no I/O; SI units, joint side.
"""
from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True, inline="always")
def _piece(x: float, v: float, hl: float, kl: float, dl: float, k_half: float, g: float, tr: float):
    """The contact's piece at deflection x (rad) and rate v (rad/s), for both branches of :func:`link_torques`:
    its stiffness d force / d delta (k in contact plus the gravity stiffness g), its damping, its constant part
    (k b/2 side - tau_r) and the force at (x, v) (force - stiff x - damp v). side: +1, -1 in contact, 0 in the gap."""
    side = (1.0 if x > hl else 0.0) - (1.0 if x < -hl else 0.0)
    touch = abs(side)
    stiff = kl * touch + g
    damp = dl * touch
    force = k_half * side - tr
    return stiff, damp, force, (force - stiff * x) - damp * v


@njit(cache=True, nogil=True)
def link_torques(hm: np.ndarray, tau_r: np.ndarray, gp: np.ndarray, owner: np.ndarray, half: np.ndarray,
                 k: np.ndarray, d: np.ndarray, h: float, n_sub: int, delta0: np.ndarray) -> np.ndarray:
    """Gear torque minus the rigid model's torque, (N, L), of L links each behind a spring with a dead zone.

    hm (N, n): the sub-step over the joint's inertia h / M_jj (s / (kg m^2)); tau_r (N, n): the rigid model's joint
    torque (N*m); gp (N, n): its gravity stiffness d tau_r / d q_j (N*m/rad); owner (L,): each lane's joint; half,
    k, d (L,): half the gap (rad), the stiffness (N*m/rad) and the damping (N*m*s/rad) of each lane; h: the sub-step
    (s), n_sub per sample; delta0 (L,): the deflection at the first sample (rad), at rest (velocity 0).

    M_jj delta_dd = tau_s(delta, delta_d) - tau_r - G' delta with tau_s = -k (delta - clip(delta, -b/2, b/2)) -
    d delta_d in contact: the theta-method on the contact's piecewise-linear force, trapezoidal (theta 1/2, no
    numerical damping) where the sub-step resolves the piece, backward Euler (theta 1) where it does not. Where every
    lane resolves both pieces at a sample (nearly always) the trapezoidal form is written with the halvings taken
    out (exact in binary floating point), as the vectorised loop wrote it.
    """
    N = hm.shape[0]
    L = owner.shape[0]
    out = np.empty((N, L))
    delta = delta0.copy()
    ddelta = np.zeros(L)
    h_half = h * 0.5
    for i in range(N):
        resolved = True
        for lane in range(L):
            j = owner[lane]
            hm_l = hm[i, j]
            g = gp[i, j]
            if not ((hm_l * (d[lane] + h * abs(k[lane] + g)) < 1.0) and (hm_l * (h * abs(g)) < 1.0)):
                resolved = False
                break
        for lane in range(L):
            j = owner[lane]
            hm_l = hm[i, j]
            tr = tau_r[i, j]
            g = gp[i, j]
            kl, dl, hl = k[lane], d[lane], half[lane]
            k_half = kl * hl
            x, v = delta[lane], ddelta[lane]
            if resolved:
                hm2 = hm_l * 0.5
                for _ in range(n_sub):
                    stiff, damp, force, f0 = _piece(x, v, hl, kl, dl, k_half, g, tr)
                    num = (((force - (h_half * v + x) * stiff) + f0) * hm2) + v
                    den = ((h_half * stiff + damp) * hm2) + 1.0
                    v1 = num / den
                    x = x + (v + v1) * h_half
                    v = v1
            else:
                for _ in range(n_sub):
                    stiff, damp, force, f0 = _piece(x, v, hl, kl, dl, k_half, g, tr)
                    th = 0.5 if hm_l * (damp + h * abs(stiff)) < 1.0 else 1.0
                    omt = 1 - th
                    v_new = (v + hm_l * (omt * f0 + th * (force - stiff * (x + h * omt * v)))) \
                        / max(1.0 + hm_l * th * (damp + h * th * stiff), 0.25)
                    x = x + h * (omt * v + th * v_new)
                    v = v_new
            delta[lane], ddelta[lane] = x, v
            excess = x - min(max(x, -hl), hl)
            out[i, lane] = -kl * excess - dl * v * (1.0 if excess != 0 else 0.0) - tr
    return out
