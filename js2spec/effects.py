"""The effect kinds, as data: the one definition of what the simulator can hide and the diagnosis can name.

Effects are physics an identified model (eq. 1) leaves out. ``hil_sim`` simulates them (``sim_truth.yaml``
``effects:``, ``Plant(effects=...)``); ``diagnosis`` names and fits them and writes them back in the same form
(``effects.yaml``, ``model_diagnosed.yaml`` ``unmodelled:``). Both read the kinds, parameter names, units, ranges
and defaults from :data:`EFFECT_KINDS` here, and both validate with :func:`parse_effects`.

Config form (a list of mappings)::

    effects:
      - {kind: stribeck, joints: [1], velocity: 2.0}
      - {kind: joint_elasticity, joints: [j2], stiffness: 4000.0, damping: 8.0}

``joints`` lists 0-based drive indices or joint names (``drives.yaml`` ``joints``); ``payload_change`` defaults to the
last joint (the hand). "motor side" means the motor shaft (the coordinate of eq. 1's ``J_a``, ``B``, ``f_c``); "joint
side" the link side of the gear.

Checks (``Param.check``): ``pos`` > 0, ``nonneg`` >= 0, ``any`` finite, ``vec3`` 3 finite numbers, ``vec3nonneg``
3 numbers >= 0, ``fraction`` strictly between -1 and 1, ``joint`` a joint index or name other than the effect's own. A default of :data:`REQUIRED` makes the parameter required; ``None`` means "taken from another
effect" (backlash's stiffness and damping from the joint's ``joint_elasticity``).

Unknown kinds or parameters, missing required parameters, bad values and duplicate (kind, joint) pairs raise
:class:`js2spec.errors.ConfigError` naming the file and the key (``effects[i].<param>``).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .errors import ConfigError


class _Required:
    def __repr__(self) -> str:
        return "REQUIRED"


REQUIRED = _Required()
CHECKS = ("pos", "nonneg", "any", "vec3", "vec3nonneg", "fraction", "joint")


@dataclass(frozen=True)
class Param:
    """One parameter of an effect kind: name, SI unit, side/frame, check, default and meaning."""
    name: str
    unit: str                # SI unit ("-" for dimensionless)
    check: str               # one of CHECKS
    default: object          # REQUIRED, None (from another effect) or the default value
    description: str
    frame: str = ""          # "motor side", "joint side", "link frame", ...

    @property
    def required(self) -> bool:
        return self.default is REQUIRED

    def doc(self) -> str:
        """``unit, frame`` for comments and tables (e.g. ``rad/s, motor side``)."""
        return ", ".join(x for x in (self.unit, self.frame) if x)


@dataclass(frozen=True)
class Kind:
    """One effect kind: name, parameters (in order), and the physics in one sentence."""
    name: str
    params: tuple[Param, ...]
    physics: str
    default_joint: str = ""   # "last": the hand when ``joints`` is omitted

    def param(self, name: str) -> Param:
        return next(p for p in self.params if p.name == name)

    @property
    def param_names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.params)


EFFECT_KINDS: dict[str, Kind] = {k.name: k for k in (
    Kind("stribeck", (
        Param("velocity", "rad/s", "pos", REQUIRED, "Stribeck velocity v_s", "motor side"),
        Param("shape", "-", "pos", 2.0, "Stribeck exponent delta"),
        Param("static", "N*m", "nonneg", None, "breakaway friction f_s, the hump's top (default: the plant's "
                                                 "static friction, sim_truth.yaml static)", "motor side")),
        "sliding friction magnitude f_c + (f_s - f_c) exp(-(|w|/v_s)^delta): near f_s at low speed, f_c at high "
        "speed (eq. 5 becomes non-linear near 0)"),
    Kind("cogging", (
        Param("amplitude", "N*m", "nonneg", REQUIRED, "ripple amplitude A", "motor side"),
        Param("periods_per_rev", "1/rev", "pos", REQUIRED, "ripple periods p per motor revolution", "motor side"),
        Param("phase", "rad", "any", 0.0, "ripple phase phi")),
        "extra torque on the rotor A sin(p theta_m + phi), periodic in the motor angle with period 2 pi / p"),
    Kind("payload_change", (
        Param("mass", "kg", "any", REQUIRED, "mass added to the link (may be < 0 if the link keeps a positive mass)"),
        Param("com", "m", "vec3", [0.0, 0.0, 0.0], "centre of mass [x, y, z] of the added mass", "link frame"),
        Param("inertia", "kg*m^2", "vec3nonneg", [0.0, 0.0, 0.0], "[ixx, iyy, izz] about com", "link frame")),
        "a point mass (plus inertia) added to the link moved by the joint; gravity torque changes by m g r",
        default_joint="last"),
    Kind("thermal_drift", (
        Param("heating", "K/A^2", "nonneg", 0.0, "steady-state temperature rise per squared current (copper losses)"),
        Param("time_constant", "s", "pos", REQUIRED, "thermal time constant"),
        Param("friction_per_kelvin", "1/K", "any", REQUIRED, "relative friction change alpha per kelvin"),
        Param("initial_rise", "K", "nonneg", 0.0, "temperature rise at the start"),
        Param("friction_power_heating", "K/W", "nonneg", 0.0, "steady-state temperature rise per watt of friction "
                                                               "power |f w| (the gear and bearings warming)",
              "motor side")),
        "first-order temperature rise dT/dt = (heating I^2 + friction_power_heating |f w| - dT)/time_constant, I the "
        "motor current, f w the friction power at the motor; B, f_c, f_s are scaled by max(0, 1 + alpha dT)"),
    Kind("load_dependent_friction", (
        Param("coefficient", "-", "nonneg", REQUIRED, "mu: N*m of friction per N*m of transmitted load"),),
        "f_c and f_s grow by mu |tau_load|, tau_load the motor-side torque the gear transmits to the links "
        "(tau_m - f - J_a theta_m_dd)"),
    Kind("asymmetric_friction", (
        Param("negative_scale", "-", "nonneg", REQUIRED, "factor on f_c, f_s in the negative direction"),),
        "f_c and f_s (and the Stribeck hump) in the negative direction are multiplied by negative_scale"),
    Kind("joint_elasticity", (
        Param("stiffness", "N*m/rad", "pos", REQUIRED, "spring stiffness k", "joint side"),
        Param("damping", "N*m*s/rad", "nonneg", 0.0, "spring damping d", "joint side")),
        "two-mass joint: a spring-damper between the gear output K theta_m + offset and the link; link angle = "
        "gear angle + deflection, deflection at rest -tau_link/k"),
    Kind("torque_offset", (
        Param("offset", "N*m", "any", REQUIRED, "constant load torque on the rotor, which the drive supplies on top "
                                                "of eq. 1", "motor side"),),
        "a constant torque acting on the motor against the drive (a preload, a cable, a counterbalance's error, a "
        "torque zero that moved): the measured torque is eq. 1's plus the offset, in both directions and at rest"),
    Kind("coupling", (
        Param("from_joint", "-", "joint", REQUIRED, "the joint whose motion also turns the effect's joint (0-based "
                                                   "index or name)"),
        Param("coefficient", "rad/rad", "fraction", REQUIRED, "c: rad the effect's joint turns per rad of from_joint "
                                                              "besides the model's K (|c| < 1)", "joint side")),
        "a transmission (gear matrix) error: the arm's joint-from-motor matrix is K_true = (I + c e_j e_i^T) K "
        "(i = from_joint, j the effect's joint): joint j turns c rad more per rad of joint i than K says, and motor i "
        "carries c tau_j more of joint j's torque (motor torques K_true^T tau); the encoders read the motors, the "
        "drives and the model use K"),
    Kind("backlash", (
        Param("width", "rad", "pos", REQUIRED, "total play b", "joint side"),
        Param("stiffness", "N*m/rad", "pos", None, "contact stiffness (default: the joint's joint_elasticity "
                                                   "stiffness, required without it)", "joint side"),
        Param("damping", "N*m*s/rad", "nonneg", None, "contact damping (default: the elasticity's, else 0)",
              "joint side")),
        "dead zone of width b in that spring: no torque is transmitted while |deflection| < b/2 (lost motion on "
        "reversal)"),
)}

KIND_NAMES: tuple[str, ...] = tuple(EFFECT_KINDS)


@dataclass(frozen=True)
class Effect:
    """One configured effect: ``kind``, the 0-based drive/joint indices it applies to, and its parameters (SI)."""
    kind: str
    joints: tuple[int, ...]
    params: dict = field(default_factory=dict)

    def __getitem__(self, key):
        return self.params[key]

    def as_config(self) -> dict:
        """Back to the config form (``{kind, joints, <params>}``, plain floats and lists)."""
        out: dict = {"kind": self.kind, "joints": list(self.joints)}
        for k, v in self.params.items():
            if v is not None:
                out[k] = np.asarray(v, float).tolist() if isinstance(v, np.ndarray) else v
        return out


def check_value(value, check: str, source, key: str):
    """Validate one parameter value against its check; return it as float (or a (3,) array). ``joint`` checks are
    done in :func:`parse_effects` (they need the joint names)."""
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
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) \
            or not np.isfinite(value):
        raise ConfigError(source, key, f"must be a finite number, got {value!r}")
    value = float(value)
    if check == "pos" and value <= 0:
        raise ConfigError(source, key, f"must be > 0, got {value}")
    if check == "nonneg" and value < 0:
        raise ConfigError(source, key, f"must be >= 0, got {value}")
    if check == "fraction" and not -1.0 < value < 1.0:
        raise ConfigError(source, key, f"must be between -1 and 1 (exclusive), got {value}")
    return value


def _joint_index(j, n: int, joints, source, key: str) -> int:
    """A 0-based joint index or a joint name (``drives.yaml`` ``joints``) -> the index; else a ConfigError."""
    if isinstance(j, str) and joints is not None and j in joints:
        j = joints.index(j)
    if isinstance(j, np.integer):
        j = int(j)
    if isinstance(j, bool) or not isinstance(j, int) or not 0 <= j < n:
        raise ConfigError(source, key, f"{j!r} is not a joint (0..{n - 1}" + (f" or one of {joints})" if joints else ")"))
    return j


def parse_effects(items, n: int, source: str | Path | None = None, joints: list[str] | None = None,
                  prefix: str = "effects") -> list[Effect]:
    """Validate a list of effect mappings against :data:`EFFECT_KINDS`; return :class:`Effect` objects."""
    if isinstance(items, dict):
        items = [items]
    if not isinstance(items, (list, tuple)):
        raise ConfigError(source, prefix, f"must be a list of effects, got {type(items).__name__}")
    out: list[Effect] = []
    seen: set[tuple] = set()
    for i, item in enumerate(items):
        where = f"{prefix}[{i}]"
        if isinstance(item, Effect):
            out.append(item)
            continue
        if not isinstance(item, dict):
            raise ConfigError(source, where, f"must be a mapping with 'kind', got {item!r}")
        kind = item.get("kind")
        if kind not in EFFECT_KINDS:
            raise ConfigError(source, f"{where}.kind",
                              f"unknown effect {kind!r} (known: {', '.join(sorted(EFFECT_KINDS))})")
        spec = EFFECT_KINDS[kind]
        unknown = sorted(set(item) - set(spec.param_names) - {"kind", "joints"})
        if unknown:
            raise ConfigError(source, f"{where}.{unknown[0]}",
                              f"unknown parameter of {kind} (known: joints, {', '.join(spec.param_names)})")
        if "joints" in item:
            js = item["joints"]
        elif spec.default_joint == "last":
            js = [n - 1]
        else:
            raise ConfigError(source, f"{where}.joints", "missing (list of 0-based joint indices or joint names)")
        if isinstance(js, (int, str, np.integer)) and not isinstance(js, bool):
            js = [js]
        if not isinstance(js, (list, tuple)) or not js:
            raise ConfigError(source, f"{where}.joints", f"must be a non-empty list, got {js!r}")
        idx = []
        # a coupling is one per (driven joint, source joint): the source is part of its key
        src = item.get("from_joint") if kind == "coupling" else None
        src = _joint_index(src, n, joints, source, f"{where}.from_joint") if src is not None else None
        for j in js:
            j = _joint_index(j, n, joints, source, f"{where}.joints")
            if (kind, j, src) in seen:
                raise ConfigError(source, f"{where}.joints", f"{kind} is configured twice on joint {j}")
            if src is not None and src == j:
                raise ConfigError(source, f"{where}.from_joint", f"is the effect's own joint {j}: a coupling links "
                                                                 "two different joints")
            seen.add((kind, j, src))
            idx.append(j)
        params = {}
        for p in spec.params:
            if p.name in item and item[p.name] is not None:
                if p.check == "joint":
                    params[p.name] = src
                    continue
                params[p.name] = check_value(item[p.name], p.check, source, f"{where}.{p.name}")
            elif p.required:
                raise ConfigError(source, f"{where}.{p.name}",
                                  f"missing (required parameter of {kind}: {p.description}, {p.doc()})")
            else:
                params[p.name] = np.asarray(p.default, dtype=float) if isinstance(p.default, list) else p.default
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


def units_comment() -> str:
    """One comment line per kind: its parameters with their units (for the head of a written ``effects.yaml``)."""
    lines = []
    for k in EFFECT_KINDS.values():
        lines.append(f"#   {k.name}: " + "; ".join(f"{p.name} ({p.doc()})" for p in k.params))
    return "\n".join(lines)


def markdown_table() -> str:
    """The kinds as a Markdown table (kind | parameters (unit) | physics), for docs."""
    rows = ["| kind | parameters (unit) | physics |", "| --- | --- | --- |"]
    for k in EFFECT_KINDS.values():
        ps = "; ".join(f"``{p.name}`` ({p.doc()}" + (", required" if p.required else
                                                     f", default {p.default}" if p.default is not None else "")
                       + ")" for p in k.params)
        rows.append(f"| ``{k.name}`` | {ps} | {k.physics} |")
    return "\n".join(rows)
