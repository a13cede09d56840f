"""A physically consistent set of standard parameters that agrees with the identified base parameters.

Base parameters (``beta = E pi``) can be any numbers; a simulator needs, per link, a positive mass, a centre of mass
and an inertia tensor that is positive definite and satisfies the triangle inequalities (a real body). Every such body
has a positive-definite 4x4 pseudo-inertia ``J = [[Sigma, h], [h^T, m]]`` with ``Sigma = 1/2 tr(I) 1 - I``
(Wensing et al. 2017); the log-Cholesky factor ``J = U U^T`` (U upper triangular with ``exp`` on the diagonal,
Rucker & Wensing 2022) maps 10 free numbers onto exactly these bodies. Motor inertias are kept >= 0 (squared).

We minimise, over the link parameters (log-Cholesky) and motor inertias,

    (E pi - beta_hat)^T A (E pi - beta_hat) / (N s^2)  +  lam * || (pi_links - pi_urdf) / scale ||^2

where A = W_b^T W_b is the base regressor's Gram matrix on the fitting data (so the first term is the rise in the
torque residual, in units of its noise variance, corrected for the filtered rows' correlation) and the prior keeps the
directions the data cannot see at the URDF's values: with ``lam = 1`` a parameter leaves its URDF value by its own
magnitude only if that buys one unit of chi-square in the fit. (On the KUKA LWR4+, 0.01 let a weakly seen link mass
reach 33 kg for the same validation error; 1 keeps it at 9 kg and validates better on another trajectory.) ``scipy.optimize.least_squares`` (trust region), friction is taken as identified.
"""
from __future__ import annotations

import numpy as np
from scipy.optimize import least_squares


def pseudo_from_params(p10: np.ndarray) -> np.ndarray:
    """Pinocchio dynamic parameters [m, mcx, mcy, mcz, Ixx, Ixy, Iyy, Ixz, Iyz, Izz] (about the frame origin) ->
    pseudo-inertia J (4x4)."""
    m, hx, hy, hz, ixx, ixy, iyy, ixz, iyz, izz = p10
    I = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
    S = 0.5 * np.trace(I) * np.eye(3) - I
    J = np.zeros((4, 4))
    J[:3, :3] = S
    J[:3, 3] = J[3, :3] = [hx, hy, hz]
    J[3, 3] = m
    return J


def params_from_pseudo(J: np.ndarray) -> np.ndarray:
    S = J[:3, :3]
    I = np.trace(S) * np.eye(3) - S
    h = J[:3, 3]
    return np.array([J[3, 3], h[0], h[1], h[2], I[0, 0], I[0, 1], I[1, 1], I[0, 2], I[1, 2], I[2, 2]])


_IU = np.triu_indices(4)


def logchol_to_pseudo(th: np.ndarray) -> np.ndarray:
    U = np.zeros((4, 4))
    U[_IU] = th
    d = np.diag_indices(4)
    U[d] = np.exp(np.clip(U[d], -40.0, 20.0))
    return U @ U.T


def pseudo_to_logchol(J: np.ndarray) -> np.ndarray:
    # J = U U^T with U upper triangular: flip to use the lower Cholesky
    P = np.eye(4)[::-1]
    L = np.linalg.cholesky(P @ J @ P)
    U = P @ L @ P
    U = U.copy()
    d = np.diag_indices(4)
    U[d] = np.log(U[d])
    return U[_IU]


def is_physical(p10: np.ndarray, tol: float = 0.0) -> bool:
    """Positive mass, PD rotational inertia about the COM, triangle inequalities."""
    m = p10[0]
    if m <= 0:
        return False
    c = p10[1:4] / m
    ixx, ixy, iyy, ixz, iyz, izz = p10[4:]
    Io = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
    Ic = Io - m * (np.dot(c, c) * np.eye(3) - np.outer(c, c))
    ev = np.linalg.eigvalsh(Ic)
    if ev.min() <= -tol:
        return False
    a, b, cc = ev
    return a + b >= cc - tol and a + cc >= b - tol and b + cc >= a - tol


def nearest_physical(p10: np.ndarray, floor_mass: float = 1e-3) -> np.ndarray:
    """Project a (possibly unphysical) parameter set onto a physical one (eigenvalue clipping of J)."""
    J = pseudo_from_params(p10)
    J = 0.5 * (J + J.T)
    w, V = np.linalg.eigh(J)
    w = np.maximum(w, 1e-9 * max(abs(w).max(), 1e-9))
    J = V @ np.diag(w) @ V.T
    if J[3, 3] < floor_mass:
        J *= floor_mass / max(J[3, 3], 1e-12)
    return params_from_pseudo(J)


class PhysicalConsistencyFit:
    """Fit physically consistent standard parameters to base parameters (see module docstring).

    ``fit(E, beta_hat, gram, inertial_nominal, n_links, motor_cols, fixed, nonneg_cols=())``: ``E`` (r, p) base map
    restricted to the parameters being fitted, ``gram`` (r x r) data information matrix (A / (N s^2)), ``fixed`` (p,)
    values for columns not fitted (e.g. friction from the sequential tests), NaN where fitted. Motor inertias and the
    ``nonneg_cols`` (viscous B and Coulomb f_c when friction is fitted here) are kept >= 0 (squared); other free
    columns (offsets) are unconstrained. After it: ``links_`` (n_links, 10), ``motor_inertia_``, ``pi_`` (p,),
    ``beta_`` (E pi), ``physical_`` (bool per link), ``cost_``.
    """

    def __init__(self, prior_weight: float = 1.0, max_nfev: int = 200, min_thickness: float = 1e-3):
        self.prior_weight = prior_weight
        self.max_nfev = max_nfev
        self.min_thickness = min_thickness

    def fit(self, E, beta_hat, gram, inertial_nominal, n_links, motor_cols, fixed, nonneg_cols=()):
        E = np.asarray(E, float)
        p = E.shape[1]
        nl = 10 * n_links
        fixed = np.asarray(fixed, float)
        motor_only = np.asarray(motor_cols, int)
        motor_cols = sorted(set(int(j) for j in motor_cols) | {int(j) for j in nonneg_cols if np.isnan(fixed[j])})
        free_other = [j for j in range(nl, p) if np.isnan(fixed[j]) and j not in set(motor_cols)]
        L = np.linalg.cholesky(gram + 1e-12 * np.trace(gram) / len(gram) * np.eye(len(gram))).T
        nom = np.asarray(inertial_nominal, float).reshape(n_links, 10)
        th0 = []
        for i in range(n_links):
            pi_i = nom[i] if is_physical(nom[i]) else nearest_physical(nom[i])
            th0.append(pseudo_to_logchol(pseudo_from_params(pi_i)))
        th0 = np.concatenate(th0)
        # scales for the prior: the link's mass, first moment and inertia magnitudes
        sc = []
        for i in range(n_links):
            m = max(nom[i, 0], 1e-2)
            h = max(np.linalg.norm(nom[i, 1:4]), 0.05 * m * 0.1)
            I = max(np.abs(nom[i, 4:]).max(), 1e-6)
            sc.append(np.r_[m, h, h, h, I, I, I, I, I, I])
        sc = np.concatenate(sc)
        base_fixed = np.where(np.isnan(fixed), 0.0, fixed)
        mc = np.asarray(motor_cols, int)

        def assemble(x):
            pi = base_fixed.copy()
            links = np.concatenate([params_from_pseudo(logchol_to_pseudo(x[10 * i:10 * i + 10]))
                                    for i in range(n_links)])
            pi[:nl] = links
            k = nl + 0
            xm = x[10 * n_links:10 * n_links + len(mc)]
            pi[mc] = xm ** 2
            xo = x[10 * n_links + len(mc):]
            pi[free_other] = xo
            return pi

        # motor inertias start from the base parameter that leads with them, else 0
        ja0 = np.zeros(len(mc))
        xo0 = np.zeros(len(free_other))
        x0 = np.concatenate([th0, np.sqrt(np.abs(ja0)) + 1e-4, xo0])
        # refine the start of the linear part (motor inertias, friction, offsets): least squares with links at
        # nominal, in the data's metric
        pi_nom = assemble(x0)
        lin = list(mc) + list(free_other)
        Am = L @ E[:, lin]
        resid0 = L @ (beta_hat - E @ np.where(np.isin(np.arange(p), lin), 0.0, pi_nom))
        sol_lin, *_ = np.linalg.lstsq(Am, resid0, rcond=None)
        x0[10 * n_links:10 * n_links + len(mc)] = np.sqrt(np.clip(sol_lin[:len(mc)], 1e-12, None))
        x0[10 * n_links + len(mc):] = sol_lin[len(mc):]
        lam = np.sqrt(self.prior_weight)

        def res(x):
            pi = assemble(x)
            r1 = L @ (E @ pi - beta_hat)
            r2 = lam * (pi[:nl] - nom.reshape(-1)) / sc
            return np.concatenate([r1, r2])

        LE = L @ E
        nx = len(x0)

        def jac(x):
            # d pi / d x: links via dJ = dU U^T + U dU^T (log-Cholesky), motor inertias 2 x, others identity
            D = np.zeros((p, nx))
            for i in range(n_links):
                th = x[10 * i:10 * i + 10]
                U = np.zeros((4, 4))
                U[_IU] = th
                dg = np.diag_indices(4)
                U[dg] = np.exp(np.clip(U[dg], -40.0, 20.0))
                for k, (a, b) in enumerate(zip(*_IU)):
                    dU = np.zeros((4, 4))
                    dU[a, b] = U[a, b] if a == b else 1.0
                    dJ = dU @ U.T + U @ dU.T
                    D[10 * i:10 * i + 10, 10 * i + k] = params_from_pseudo(dJ)
            xm = x[10 * n_links:10 * n_links + len(mc)]
            D[mc, 10 * n_links + np.arange(len(mc))] = 2 * xm
            for k, j in enumerate(free_other):
                D[j, 10 * n_links + len(mc) + k] = 1.0
            return np.vstack([LE @ D, lam * D[:nl] / sc[:, None]])

        sol = least_squares(res, x0, jac=jac, method="trf", max_nfev=self.max_nfev, x_scale=1.0, ftol=1e-12,
                            xtol=1e-12, gtol=1e-10)
        self.sol_ = sol
        pi = assemble(sol.x)
        # keep every body strictly inside the physical set: second moments of at least m * (1 mm)^2 about each axis
        # (a body at least ~1 mm thick), so rounding in the URDF cannot break a triangle inequality
        for i in range(n_links):
            J = pseudo_from_params(pi[10 * i:10 * i + 10])
            m = J[3, 3]
            c = J[:3, 3] / m
            S_com = J[:3, :3] - m * np.outer(c, c)
            ev = np.linalg.eigvalsh(S_com)
            floor = m * self.min_thickness ** 2
            if ev.min() < floor:
                J[:3, :3] += (floor - ev.min()) * np.eye(3)
                pi[10 * i:10 * i + 10] = params_from_pseudo(J)
        self.pi_ = pi
        self.links_ = pi[:nl].reshape(n_links, 10)
        self.motor_inertia_ = pi[motor_only]
        self.beta_ = E @ pi
        self.physical_ = np.array([is_physical(l, tol=1e-12) for l in self.links_])
        self.cost_ = float(sol.cost)
        self.success_ = bool(sol.success)
        return self
