"""Effects the identified model (eq. 1) does not have, switchable per joint by config.

They exist so that a later mismatch diagnosis can be proven on data where one is concealed. The kinds, their
parameters, units, ranges and defaults are defined once, as data, in :mod:`js2spec.effects` (``EFFECT_KINDS``),
which the diagnosis uses too; this module is the simulator's view of it. Config form (``sim_truth.yaml``
``effects:`` or ``Plant(..., effects=[...])``)::

    effects:
      - {kind: stribeck, joints: [1], velocity: 2.0}
      - {kind: joint_elasticity, joints: [j2], stiffness: 4000.0, damping: 8.0}

The physics of each kind is implemented in :mod:`hil_sim.friction` (stribeck, asymmetric_friction,
load_dependent_friction, thermal_drift), :mod:`hil_sim.dynamics` (payload_change, joint_elasticity, backlash) and
:mod:`hil_sim.plant` (cogging, the thermal state, the spring forces, coupling: the true gear matrix that
:class:`hil_sim.dynamics.ArmDynamics` then uses). ``js2spec.effects.markdown_table()`` prints the
table of kinds, parameters (unit) and physics.

Unknown kinds or parameters, missing required parameters, bad values and duplicate (kind, joint) pairs raise
:class:`js2spec.errors.ConfigError` naming the file and the key (``effects[i].<param>``).
"""
from __future__ import annotations

from js2spec.effects import EFFECT_KINDS, REQUIRED, Effect, parse_effects

# kind -> {param: (default or REQUIRED, check, unit and side)}: the schema's view used by older callers
EFFECT_PARAMS: dict[str, dict[str, tuple]] = {
    k.name: {p.name: (p.default, p.check, p.doc()) for p in k.params} for k in EFFECT_KINDS.values()}

__all__ = ["EFFECT_KINDS", "EFFECT_PARAMS", "REQUIRED", "Effect", "parse_effects"]
