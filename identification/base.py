"""Base parameters: the identifiable linear combinations of the standard parameters of eq. 1.

Many standard parameters never act on the torques alone (e.g. the mass of link 1 of a vertical first joint) or act only
in fixed combinations (the motor inertia J_a1 and the inertia of link 1 about the vertical axis both multiply
theta_m1_dd). Column-pivoted QR of the regressor evaluated on random states separates them (Gautier 1990):

    W P = Q [R1 R2]   ->   W pi = W_b beta,   beta = pi_b + R1^-1 R2 pi_d

``BaseParameters.E`` is the (n_base x n_std) matrix with ``beta = E pi``; ``names`` spell each combination as
``lead + c1*other1 + ...``. Columns are normalised before the QR so the rank decision does not depend on units.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla

from .regressor import ArmModel, build_regressor, column_groups, standard_names


@dataclass
class BaseParameters:
    std_names: list[str]        # standard parameter names (length p)
    base_index: np.ndarray      # columns of the standard regressor kept as base columns (length r)
    E: np.ndarray               # (r, p): beta = E @ pi
    names: list[str]            # readable combination names (length r)
    zero_index: np.ndarray      # standard parameters with no effect on the torques at all
    col_scale: np.ndarray | None = None   # base column i = col_scale[i] * standard column base_index[i]
    lead_index: np.ndarray | None = None  # the standard parameter each base parameter is named after

    @property
    def n(self) -> int:
        return len(self.base_index)

    def project(self, W: np.ndarray) -> np.ndarray:
        """Base regressor: the base columns of a standard regressor (last axis). ``W @ pi == project(W) @ E @ pi``."""
        Wb = W[..., self.base_index]
        if self.col_scale is not None:
            Wb = Wb * self.col_scale
        return Wb

    def beta(self, pi: np.ndarray) -> np.ndarray:
        """Base parameter values of a standard parameter vector."""
        return self.E @ pi

    def lead(self, i: int) -> str:
        li = self.base_index if self.lead_index is None else self.lead_index
        return self.std_names[li[i]]

    def members(self, i: int, tol: float = 1e-9) -> list[str]:
        return [self.std_names[j] for j in np.flatnonzero(np.abs(self.E[i]) > tol)]

    def index_of(self, std_name: str) -> int | None:
        """Index of the base parameter whose combination contains the standard parameter ``std_name``."""
        j = self.std_names.index(std_name)
        hits = np.flatnonzero(np.abs(self.E[:, j]) > 1e-12)
        if len(hits) == 0:
            return None
        # prefer the one where it is the lead
        li = self.base_index if self.lead_index is None else self.lead_index
        for h in hits:
            if li[h] == j:
                return int(h)
        return int(hits[np.argmax(np.abs(self.E[hits, j]))])

    def is_alone(self, std_name: str) -> bool:
        """True when ``std_name`` is a base parameter by itself (identifiable separately)."""
        i = self.index_of(std_name)
        return i is not None and self.members(i) == [std_name]

    def subset(self, keep: np.ndarray) -> "BaseParameters":
        keep = np.asarray(keep)
        return BaseParameters(self.std_names, self.base_index[keep], self.E[keep], [self.names[i] for i in keep],
                              self.zero_index, None if self.col_scale is None else self.col_scale[keep],
                              None if self.lead_index is None else self.lead_index[keep])


def _fmt(c: float) -> str:
    return f"{c:.6g}"


def base_parameters(arm: ArmModel, offsets: bool = False, n_samples: int = 400, seed: int = 0,
                    rtol: float = 1e-8, prefer: tuple = ("Ja_",), sqrt_viscous: bool = False) -> BaseParameters:
    """Structural base parameters of ``arm`` by pivoted QR on random states (joint angles uniform on +-pi).

    A combination that holds a parameter named ``prefer`` (the motor inertias: the paper's J_a) is named and scaled
    after it (``Ja_2 + 0.0001*Iyy_link2 + ...`` rather than ``Iyy_link2 + ... + 10000*Ja_2``): the same base
    parameter divided by its J_a coefficient, its regressor column multiplied by it."""
    rng = np.random.default_rng(seed)
    n = arm.n
    qj = rng.uniform(-np.pi, np.pi, size=(n_samples, n))
    dqj = rng.normal(size=(n_samples, n)) * 2.0
    ddqj = rng.normal(size=(n_samples, n)) * 5.0
    Kinv = arm.Kinv
    qm = (qj - arm.joint_offset) @ Kinv.T
    W = build_regressor(arm, qm, dqj @ Kinv.T, ddqj @ Kinv.T, offsets=offsets, sqrt_viscous=sqrt_viscous)
    W = W.reshape(-1, W.shape[-1])
    names = standard_names(arm, offsets, sqrt_viscous)
    norms = np.linalg.norm(W, axis=0)
    scale_ref = norms.max()
    nonzero = norms > 1e-12 * scale_ref
    cols = np.flatnonzero(nonzero)
    Wn = W[:, cols] / norms[cols]
    _, R, piv = sla.qr(Wn, mode="economic", pivoting=True)
    d = np.abs(np.diag(R))
    r = int(np.sum(d > rtol * d[0]))
    R1, R2 = R[:r, :r], R[:r, r:]
    G = sla.solve_triangular(R1, R2)  # normalised: beta_n = pi_b,n + G pi_d,n
    base_cols = cols[piv[:r]]
    dep_cols = cols[piv[r:]]
    p = W.shape[1]
    E = np.zeros((r, p))
    E[np.arange(r), base_cols] = 1.0
    # un-normalise: column j normalised by norms[j]  ->  beta_i = pi_bi + sum_j G_ij * norms[dj]/norms[bi] * pi_dj
    E[:, dep_cols] = G * norms[dep_cols][None, :] / norms[base_cols][:, None]
    E[np.abs(E) < 1e-10 * np.abs(E).max()] = 0.0
    # name (and scale) a combination after a preferred member (J_a)
    lead = base_cols.copy()
    scale = np.ones(r)
    for i in range(r):
        for j in np.flatnonzero(E[i]):
            if j != base_cols[i] and names[j].startswith(prefer):
                c = E[i, j]
                E[i] = E[i] / c
                scale[i] = c
                lead[i] = j
                break
    # order the base parameters as the standard ones (readable), not by pivot
    order = np.argsort(lead, kind="stable")
    base_cols, E, lead, scale = base_cols[order], E[order], lead[order], scale[order]
    readable = []
    for i, b in enumerate(lead):
        terms = [names[b]]
        for j in np.flatnonzero(E[i]):
            if j == b:
                continue
            c = E[i, j]
            terms.append(f"{'+' if c > 0 else '-'} {_fmt(abs(c))}*{names[j]}")
        readable.append(" ".join(terms))
    return BaseParameters(std_names=names, base_index=base_cols, E=E, names=readable,
                          zero_index=np.flatnonzero(~nonzero), col_scale=scale, lead_index=lead)


def friction_mask(bp: BaseParameters, arm: ArmModel, offsets: bool = False, sqrt_viscous: bool = False) -> np.ndarray:
    """Boolean mask over base parameters: True for the pure friction (viscous/Coulomb/offset) ones."""
    g = column_groups(arm, offsets, sqrt_viscous)
    fr = set(np.concatenate([g["viscous"], g["coulomb"], g["offset"], g["sqrt_viscous"]]).tolist())
    return np.array([set(np.flatnonzero(bp.E[i])) <= fr for i in range(bp.n)])


def condition_number(Wb: np.ndarray, normalise: bool = True) -> float:
    """2-norm condition number of a stacked base regressor (columns scaled to unit norm when ``normalise``)."""
    A = Wb.reshape(-1, Wb.shape[-1])
    G = A.T @ A                     # singular values of A = sqrt(eigenvalues of A^T A): cheaper than an SVD of A
    if normalise:
        d = np.sqrt(np.diag(G))
        d = np.where(d > 0, d, 1.0)
        G = G / np.outer(d, d)
    ev = np.linalg.eigvalsh(G)
    if ev[0] <= ev[-1] * 1e-15:
        return float(np.sqrt(ev[-1] / max(ev[0], 0.0))) if ev[0] > 0 else float("inf")
    return float(np.sqrt(ev[-1] / ev[0]))
