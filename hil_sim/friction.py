"""Motor-shaft friction of eq. 1 (``B theta_m_d + f_c sgn(theta_m_d)``) with breakaway ``f_s`` (eq. 2-3).

The friction *model* only: per-axis levels and the sliding law. Which axes stick is decided by the
time-stepping in :mod:`hil_sim.plant` (a stuck axis gets whatever friction holds it, up to ``f_s``).

Effects folded in here (parameters and units in :mod:`hil_sim.effects`): ``stribeck``, ``asymmetric_friction``,
``load_dependent_friction`` (the per-axis ``mu``) and ``thermal_drift`` (the per-axis friction scale; its
temperature state lives in the plant).
"""
from __future__ import annotations

import numpy as np


class Friction:
    """Per-motor friction parameters (motor side, SI) and the laws that use them.

    Levels in direction ``d`` (+1 or -1) for an axis with thermal scale ``s`` and transmitted load ``L``::

        f_c(d) = s * a(d) * f_c + mu |L|        f_s(d) = s * a(d) * f_s + mu |L|

    with ``a(+1) = 1``, ``a(-1) = negative_scale``. Sliding friction at velocity ``w`` in direction ``d``::

        f = s B w + d * (f_c(d) + (f_s(d) - f_c(d)) exp(-(|w| / v_s)^delta))      (Stribeck term only if configured)
    """

    def __init__(self, viscous, coulomb, static, effects=()):
        self.viscous = np.asarray(viscous, dtype=float).copy()
        self.coulomb = np.asarray(coulomb, dtype=float).copy()
        self.static = np.asarray(static, dtype=float).copy()
        n = self.n = len(self.viscous)
        self.negative_scale = np.ones(n)
        self.load_coefficient = np.zeros(n)
        self.stribeck_velocity = np.full(n, np.inf)
        self.stribeck_shape = np.full(n, 2.0)
        self.thermal_heating = np.zeros(n)
        self.thermal_time_constant = np.ones(n)
        self.thermal_alpha = np.zeros(n)
        self.thermal_initial = np.zeros(n)
        self.thermal_power_heating = np.zeros(n)     # K/W of friction power
        self.has_stribeck = self.has_load = self.has_thermal = self.has_asym = False
        for e in effects:
            j = list(e.joints)
            if e.kind == "stribeck":
                self.stribeck_velocity[j] = e["velocity"]
                self.stribeck_shape[j] = e["shape"]
                if e.params.get("static") is not None:      # the breakaway level the effect brings (f_s)
                    self.static[j] = e["static"]
                self.has_stribeck = True
            elif e.kind == "asymmetric_friction":
                self.negative_scale[j] = e["negative_scale"]
                self.has_asym = True
            elif e.kind == "load_dependent_friction":
                self.load_coefficient[j] = e["coefficient"]
                self.has_load = True
            elif e.kind == "thermal_drift":
                self.thermal_heating[j] = e["heating"]
                self.thermal_time_constant[j] = e["time_constant"]
                self.thermal_alpha[j] = e["friction_per_kelvin"]
                self.thermal_initial[j] = e["initial_rise"]
                self.thermal_power_heating[j] = e["friction_power_heating"]
                self.has_thermal = True
        self.stribeck_axes = np.flatnonzero(np.isfinite(self.stribeck_velocity))
        #: axes with any dry friction: they can stick and their velocity sign matters
        self.active = (self.coulomb > 0) | (self.static > 0) | (self.load_coefficient > 0)
        #: True when the levels never change (no asymmetry, load, heat): the plant can cache them
        self.constant = not (self.has_asym or self.has_load or self.has_thermal)

    def scale(self, temperature_rise: np.ndarray) -> np.ndarray:
        """Thermal friction scale ``max(0, 1 + alpha dT)`` per axis (``thermal_drift``)."""
        return np.maximum(0.0, 1.0 + self.thermal_alpha * temperature_rise)

    def heat_target(self, current, friction, velocity) -> np.ndarray:
        """Steady-state temperature rise for a held current (A), friction torque (N*m) and motor velocity (rad/s):
        ``heating I^2 + friction_power_heating |f w|`` (``thermal_drift``, K)."""
        return self.thermal_heating * current ** 2 + self.thermal_power_heating * np.abs(friction * velocity)

    def levels(self, direction, scale=None, load=None):
        """``(f_c(d), f_s(d))`` per axis for directions ``d`` (sign arrays; 0 counts as +)."""
        fc, fs = self.coulomb, self.static
        if self.has_asym:
            a = np.where(np.asarray(direction) < 0, self.negative_scale, 1.0)
            fc, fs = fc * a, fs * a
        if scale is not None:
            fc, fs = fc * scale, fs * scale
        if load is not None and self.has_load:
            extra = self.load_coefficient * np.abs(load)
            fc, fs = fc + extra, fs + extra
        return fc, fs

    def sliding(self, velocity, sign, fc, fs, scale=None):
        """Friction torque opposing motion: ``B w + sign (f_c + Stribeck hump)``; ``sign`` frozen per step.

        Axes with ``sign == 0`` (no dry friction, or at rest) get only the viscous part.
        """
        b = self.viscous if scale is None else self.viscous * scale
        f = b * velocity + sign * fc
        if self.has_stribeck:
            k = self.stribeck_axes
            hump = (fs[k] - fc[k]) * np.exp(-(np.abs(velocity[k]) / self.stribeck_velocity[k]) ** self.stribeck_shape[k])
            f[k] += sign[k] * hump
        return f

    def sliding_at(self, velocity, scale=None, load=None):
        """Sliding friction at given velocities (sign taken from the velocity); for checks and plots."""
        sign = np.sign(velocity) * self.active
        fc, fs = self.levels(sign, scale, load)
        return self.sliding(np.asarray(velocity, dtype=float), sign, fc, fs, scale)
