"""Is the identified model a plausible arm? Checks that turn into a FAIL verdict with one sentence each.

* **signs**: every link mass, motor inertia J_a, viscous B and Coulomb f_c of the exported model is >= 0;
* **mass band**: the total mass within ``TOTAL_MASS_BAND`` x the nominal URDF's, each link within
  ``LINK_MASS_FACTOR`` x its nominal mass (+ ``LINK_MASS_SLACK_KG`` for light links);
* **units**: the gravity torques of the data-only estimate (the chosen method's base parameters, offsets left out)
  against the nominal URDF's at the fit poses, per axis whose nominal gravity torque is not negligible. A ratio far
  from 1 near a factor that units explain (1000, 180/pi, the axis's gear ratio) is reported as such:
  "torques look 1000x too large: check the units".
"""
from __future__ import annotations

import numpy as np

from .regressor import build_regressor, standard_vector

TOTAL_MASS_BAND = (0.5, 2.0)
LINK_MASS_FACTOR = 4.0
LINK_MASS_SLACK_KG = 0.5
GRAVITY_RATIO_BAND = (0.5, 2.0)     # identified / nominal gravity torque outside this: the units check fails
FACTOR_TOLERANCE = 0.25             # a ratio within 25 % of a known factor is attributed to it


def _check(name: str, ok: bool, value, reason: str, threshold: str = "") -> dict:
    return {"check": name, "value": value, "threshold": threshold, "pass": bool(ok), "reason": None if ok else reason}


def sign_checks(ident) -> list[dict]:
    """Negative mass, J_a, B or f_c in what is exported (links, model.yaml friction and motor inertia)."""
    arm = ident.arm
    bad = []
    if ident.physical is not None:
        for lk, p in zip(arm.links, ident.physical.links_):
            if not p[0] > 0:
                bad.append(f"mass of {lk} is {p[0]:.4g} kg")
    ja, _, _ = ident.motor_inertia()
    for label, vals, unit in (("motor inertia J_a", ja, "kg m^2"), ("viscous friction B", ident.friction_viscous,
                                                                    "N m s/rad"),
                              ("Coulomb friction f_c", ident.friction_coulomb, "N m"),
                              ("square-root viscous friction Bs", ident.friction_sqrt_viscous
                               if ident.friction_sqrt_viscous is not None else [], "N m (s/rad)^0.5")):
        for j, v in zip(arm.joints, vals):
            if np.isfinite(v) and v < 0:
                bad.append(f"{label} of {j} is {v:.4g} {unit}")
    reason = ("negative physical parameters: " + "; ".join(bad[:4]) + (f" (and {len(bad) - 4} more)" if len(bad) > 4
                                                                       else "") + ": not a physical model")
    return [_check("non_negative_mass_inertia_friction", not bad, len(bad), reason, "0 negative")]


def mass_checks(ident) -> list[dict]:
    """Total and per-link masses of the exported links against the nominal URDF's."""
    if ident.physical is None:
        return []
    arm = ident.arm
    nom = np.asarray(arm.nominal_inertial, float).reshape(arm.n, 10)[:, 0]
    got = ident.physical.links_[:, 0]
    out = []
    tn, tg = float(nom.sum()), float(got.sum())
    if tn > 0:
        lo, hi = TOTAL_MASS_BAND
        ok = lo * tn <= tg <= hi * tn
        out.append(_check("total_mass_vs_urdf", ok, tg,
                          f"total link mass {tg:.3g} kg is {tg / tn:.2g}x the nominal URDF's {tn:.3g} kg (allowed "
                          f"{lo:g}-{hi:g}x): check the units of the torques and the URDF", f"{lo:g}-{hi:g}x URDF"))
    far = [f"{lk} {g:.3g} kg (nominal {m:.3g} kg)" for lk, g, m in zip(arm.links, got, nom)
           if m > 0 and not (m / LINK_MASS_FACTOR - LINK_MASS_SLACK_KG <= g <= m * LINK_MASS_FACTOR + LINK_MASS_SLACK_KG)]
    out.append(_check("link_masses_vs_urdf", not far, len(far),
                      f"link masses outside {LINK_MASS_FACTOR:g}x the URDF's: " + ", ".join(far[:3])
                      + ": the data do not support these masses (check the units and the URDF)",
                      f"within {LINK_MASS_FACTOR:g}x URDF (+{LINK_MASS_SLACK_KG:g} kg)"))
    return out


def gravity_ratio(ident, max_poses: int = 400) -> tuple[np.ndarray, np.ndarray]:
    """Per axis: RMS of the identified (data-only) gravity torque / RMS of the nominal URDF's, at the fit poses;
    and whether the axis carries a gravity torque worth comparing (> 5 % of the largest axis's)."""
    arm, bp = ident.arm, ident.bp
    offsets = ident.options.offsets
    q = np.concatenate([sig.q_motor[idx] for sig, idx in ident.fit_data["where"]])
    if len(q) > max_poses:
        q = q[np.linspace(0, len(q) - 1, max_poses).astype(int)]
    z = np.zeros_like(q)
    sqv = any(nm.startswith("Bs_") for nm in bp.std_names)
    Ws = build_regressor(arm, q, z, z, offsets=offsets, sqrt_viscous=sqv)
    beta = ident.model.beta.copy()
    for i in range(bp.n):
        if bp.lead(i).startswith("off_"):
            beta[i] = 0.0
    g_id = bp.project(Ws) @ beta
    g_nom = Ws @ standard_vector(arm, offsets=offsets, sqrt_viscous=sqv)
    r_id = np.sqrt(np.mean(g_id ** 2, axis=0))
    r_nom = np.sqrt(np.mean(g_nom ** 2, axis=0))
    loaded = r_nom > 0.05 * max(r_nom.max(), 1e-300)
    return np.where(loaded, r_id / np.where(loaded, r_nom, 1.0), np.nan), loaded


def units_checks(ident) -> list[dict]:
    """Identified vs nominal gravity torques; a ratio that looks like a unit or a gear ratio says so."""
    arm = ident.arm
    ratio, loaded = gravity_ratio(ident)
    if not loaded.any():
        return []
    gear = 1.0 / np.abs(np.diag(arm.K)) if arm.torque_side == "motor" else np.ones(arm.n)
    lo, hi = GRAVITY_RATIO_BAND
    r_all = float(np.exp(np.nanmedian(np.log(ratio[loaded]))))
    off = [k for k in range(arm.n) if loaded[k] and not lo <= ratio[k] <= hi]
    if not off:
        return [_check("gravity_torque_units", True, r_all, "", f"gravity {lo:g}-{hi:g}x URDF on every loaded axis")]
    r = r_all if not lo <= r_all <= hi else float(ratio[off[0]])
    k = off[0] if lo <= r_all <= hi else None
    factors = [(1000.0, "1000x"), (180 / np.pi, "180/pi = 57.3x (degrees?)"), (100.0, "100x"), (10.0, "10x")]
    axes = range(arm.n) if k is None else [k]
    for a in axes:
        if abs(gear[a] - 1) > 0.5:
            factors.append((float(gear[a]), f"{gear[a]:.3g}x (the gear ratio of {arm.joints[a]}: torque side?)"))
    big = r >= 1
    f = r if big else 1 / r
    name = next((txt for val, txt in factors if abs(f / val - 1) <= FACTOR_TOLERANCE), None)
    where = "" if k is None else f" on {arm.joints[k]}"
    if name is not None:
        reason = f"torques look {name} too {'large' if big else 'small'}{where}: check the units"
    else:
        reason = (f"identified gravity torques{where} are {r:.3g}x the nominal URDF's: check the units, the torque "
                  f"side and the URDF")
    return [_check("gravity_torque_units", False, r, reason, f"gravity {lo:g}-{hi:g}x URDF on every loaded axis")]


def plausibility_checks(ident) -> list[dict]:
    """All checks above, each ``{check, value, pass, reason}`` (reason: one sentence when it fails)."""
    return sign_checks(ident) + mass_checks(ident) + units_checks(ident)
