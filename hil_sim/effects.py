"""Effects the identified model (eq. 1) does not have, switchable per joint by config.

They exist so that a later mismatch diagnosis can be proven on data where one is concealed. Config form
(``sim_truth.yaml`` ``effects:`` or ``Plant(..., effects=[...])``)::

    effects:
      - {kind: stribeck, joints: [1], velocity: 2.0}
      - {kind: joint_elasticity, joints: [j2], stiffness: 4000.0, damping: 8.0}

``joints`` lists 0-based drive indices or joint names (``drives.yaml`` ``joints``). "motor side" below means the
motor shaft (the coordinate of eq. 1's ``J_a``, ``B``, ``f_c``); "joint side" means the link side of the gear.

| kind | parameters (unit) | physics |
| --- | --- | --- |
| ``stribeck`` | ``velocity`` v_s (rad/s motor, > 0); ``shape`` delta (-, > 0, default 2) | sliding friction magnitude ``f_c + (f_s - f_c) exp(-(|w|/v_s)^delta)``: near ``f_s`` at low speed, ``f_c`` at high speed (eq. 5 becomes non-linear near 0) |
| ``cogging`` | ``amplitude`` A (N*m motor, >= 0); ``periods_per_rev`` p (1/rev, > 0); ``phase`` phi (rad, default 0) | extra torque on the rotor ``A sin(p theta_m + phi)``, periodic in the motor angle with period ``2 pi / p`` |
| ``payload_change`` | ``mass`` m (kg, added; may be < 0 if the link keeps a positive mass); ``com`` (m, [x, y, z] in the link frame, default 0); ``inertia`` (kg*m^2, [ixx, iyy, izz] about ``com``, default 0) | a point mass (plus inertia) added to the link moved by the joint (default: the last joint, the hand); gravity torque changes by ``m g r`` |
| ``thermal_drift`` | ``heating`` (K/A^2, >= 0); ``time_constant`` (s, > 0); ``friction_per_kelvin`` alpha (1/K); ``initial_rise`` (K, default 0) | first-order winding temperature rise ``dT/dt = (heating I^2 - dT)/time_constant`` with ``I`` the motor current; ``B``, ``f_c``, ``f_s`` are scaled by ``max(0, 1 + alpha dT)`` |
| ``load_dependent_friction`` | ``coefficient`` mu (-, >= 0) | ``f_c`` and ``f_s`` grow by ``mu |tau_load|``, ``tau_load`` the motor-side torque the gear transmits to the links (``tau_m - f - J_a theta_m_dd``, one physics step behind) |
| ``asymmetric_friction`` | ``negative_scale`` (-, >= 0) | ``f_c`` and ``f_s`` (and the Stribeck hump) in the negative direction are multiplied by it |
| ``joint_elasticity`` | ``stiffness`` k (N*m/rad joint side, > 0); ``damping`` d (N*m*s/rad joint side, >= 0, default 0) | two-mass joint: a spring-damper between the gear output ``K theta_m + offset`` and the link; link angle = gear angle + deflection, deflection at rest ``-tau_link/k`` |
| ``backlash`` | ``width`` b (rad joint side, total play, > 0); ``stiffness`` (N*m/rad, > 0, default: the joint's ``joint_elasticity`` stiffness, required without it); ``damping`` (N*m*s/rad, default: the elasticity's, else 0) | dead zone of width ``b`` in that spring: no torque is transmitted while ``|deflection| < b/2`` (lost motion on reversal) |

Unknown kinds or parameters, missing required parameters, bad values and duplicate (kind, joint) pairs raise
:class:`js2spec.errors.ConfigError` naming the file and the key (``effects[i].<param>``).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from js2spec.errors import ConfigError

REQUIRED = object()

# kind -> {param: (default or REQUIRED, check, description)}; checks: 'pos' > 0, 'nonneg' >= 0, 'any' finite,
# 'vec3' 3 finite numbers, 'vec3nonneg' 3 numbers >= 0
EFFECT_PARAMS: dict[str, dict[str, tuple]] = {
    "stribeck": {"velocity": (REQUIRED, "pos", "rad/s motor side, Stribeck velocity"),
                 "shape": (2.0, "pos", "Stribeck exponent")},
    "cogging": {"amplitude": (REQUIRED, "nonneg", "N*m motor side"),
                "periods_per_rev": (REQUIRED, "pos", "ripple periods per motor revolution"),
                "phase": (0.0, "any", "rad")},
    "payload_change": {"mass": (REQUIRED, "any", "kg added to the link"),
                       "com": ([0.0, 0.0, 0.0], "vec3", "m, link frame"),
                       "inertia": ([0.0, 0.0, 0.0], "vec3nonneg", "kg*m^2 about com (ixx, iyy, izz)")},
    "thermal_drift": {"heating": (REQUIRED, "nonneg", "K/A^2 steady-state rise per squared current"),
                      "time_constant": (REQUIRED, "pos", "s"),
                      "friction_per_kelvin": (REQUIRED, "any", "1/K relative friction change"),
                      "initial_rise": (0.0, "nonneg", "K")},
    "load_dependent_friction": {"coefficient": (REQUIRED, "nonneg", "dimensionless, N*m friction per N*m load")},
    "asymmetric_friction": {"negative_scale": (REQUIRED, "nonneg", "dimensionless")},
    "joint_elasticity": {"stiffness": (REQUIRED, "pos", "N*m/rad joint side"),
                         "damping": (0.0, "nonneg", "N*m*s/rad joint side")},
    "backlash": {"width": (REQUIRED, "pos", "rad joint side, total play"),
                 "stiffness": (None, "pos", "N*m/rad joint side"),
                 "damping": (None, "nonneg", "N*m*s/rad joint side")},
}


@dataclass(frozen=True)
class Effect:
    """One configured effect: ``kind``, the 0-based drive/joint indices it applies to, and its parameters (SI)."""
    kind: str
    joints: tuple[int, ...]
    params: dict = field(default_factory=dict)

    def __getitem__(self, key):
        return self.params[key]


def _check_value(value, check, source, key):
    if check in ("vec3", "vec3nonneg"):
        try:
            arr = np.asarray(value, dtype=float)
        except (TypeError, ValueError):
            raise ConfigError(source, key, f"must be 3 numbers, got {value!r}") from None
        if arr.shape != (3,) or not np.all(np.isfinite(arr)):
            raise ConfigError(source, key, f"must be 3 finite numbers, got {value!r}")
        if check == "vec3nonneg" and np.any(arr < 0):
            raise ConfigError(source, key, f"must be >= 0, got {arr.tolist()}")
        return arr
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value):
        raise ConfigError(source, key, f"must be a finite number, got {value!r}")
    value = float(value)
    if check == "pos" and value <= 0:
        raise ConfigError(source, key, f"must be > 0, got {value}")
    if check == "nonneg" and value < 0:
        raise ConfigError(source, key, f"must be >= 0, got {value}")
    return value


def parse_effects(items, n: int, source: str | Path | None = None, joints: list[str] | None = None,
                  prefix: str = "effects") -> list[Effect]:
    """Validate a list of effect mappings (see the module docstring); return :class:`Effect` objects."""
    if isinstance(items, dict):
        items = [items]
    if not isinstance(items, (list, tuple)):
        raise ConfigError(source, prefix, f"must be a list of effects, got {type(items).__name__}")
    out: list[Effect] = []
    seen: set[tuple[str, int]] = set()
    for i, item in enumerate(items):
        where = f"{prefix}[{i}]"
        if isinstance(item, Effect):
            out.append(item)
            continue
        if not isinstance(item, dict):
            raise ConfigError(source, where, f"must be a mapping with 'kind', got {item!r}")
        kind = item.get("kind")
        if kind not in EFFECT_PARAMS:
            raise ConfigError(source, f"{where}.kind",
                              f"unknown effect {kind!r} (known: {', '.join(sorted(EFFECT_PARAMS))})")
        spec = EFFECT_PARAMS[kind]
        unknown = sorted(set(item) - set(spec) - {"kind", "joints"})
        if unknown:
            raise ConfigError(source, f"{where}.{unknown[0]}",
                              f"unknown parameter of {kind} (known: joints, {', '.join(spec)})")
        if "joints" in item:
            js = item["joints"]
        elif kind == "payload_change":
            js = [n - 1]
        else:
            raise ConfigError(source, f"{where}.joints", "missing (list of 0-based joint indices or joint names)")
        if isinstance(js, (int, str)) and not isinstance(js, bool):
            js = [js]
        if not isinstance(js, list) or not js:
            raise ConfigError(source, f"{where}.joints", f"must be a non-empty list, got {js!r}")
        idx = []
        for j in js:
            if isinstance(j, str) and joints is not None and j in joints:
                j = joints.index(j)
            if isinstance(j, bool) or not isinstance(j, int) or not 0 <= j < n:
                raise ConfigError(source, f"{where}.joints",
                                  f"{j!r} is not a joint (0..{n - 1}" + (f" or one of {joints})" if joints else ")"))
            if (kind, j) in seen:
                raise ConfigError(source, f"{where}.joints", f"{kind} is configured twice on joint {j}")
            seen.add((kind, j))
            idx.append(j)
        params = {}
        for p, (default, check, _desc) in spec.items():
            if p in item and item[p] is not None:
                params[p] = _check_value(item[p], check, source, f"{where}.{p}")
            elif default is REQUIRED:
                raise ConfigError(source, f"{where}.{p}", f"missing (required parameter of {kind}: {_desc})")
            else:
                params[p] = np.asarray(default, dtype=float) if isinstance(default, list) else default
        out.append(Effect(kind=kind, joints=tuple(idx), params=params))
    # cross-effect checks
    elastic = {j for e in out if e.kind == "joint_elasticity" for j in e.joints}
    for i, e in enumerate(out):
        if e.kind == "backlash" and e.params.get("stiffness") is None:
            missing = [j for j in e.joints if j not in elastic]
            if missing:
                raise ConfigError(source, f"{prefix}[{i}].stiffness",
                                  f"missing: backlash on joint(s) {missing} needs a contact stiffness "
                                  "(or a joint_elasticity effect on the same joint)")
    return out
