"""The simulator's true parameters: ``configs/<robot>/sim_truth.yaml``.

Model and data kept apart: this module only reads and validates numbers; the physics is in
:mod:`hil_sim.dynamics`, :mod:`hil_sim.friction` and :mod:`hil_sim.plant`.

Keys (motor side, SI units, lists in drive order; a single number is broadcast to every drive):

| key | unit | meaning (paper) |
| --- | --- | --- |
| ``motor_inertia`` | kg*m^2 | ``J_a`` of eq. 1, rotor + gear input, > 0 |
| ``viscous`` | N*m*s/rad | ``B`` of eq. 1 and eq. 5, >= 0 |
| ``coulomb`` | N*m | ``f_c`` of eq. 1 and eq. 5, >= 0 |
| ``static`` | N*m | breakaway friction ``f_s`` of eq. 2-3, >= coulomb |
| ``sensors.current_noise_std`` | A | white gaussian noise on the current read-back, >= 0 (optional, default 0) |
| ``integration.substeps`` | - | physics steps per drive cycle (``drives.yaml`` ``can.cycle_hz``), >= 1 (optional, default 2) |
| ``seed`` | - | default seed of the sensor noise (optional, default 0) |
| ``effects`` | - | list of effects the identified model does not have, see :mod:`hil_sim.effects` (optional) |

Unknown keys are refused (a misspelt key would otherwise silently fall back to a default).
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from js2spec.drives import parse_vector
from js2spec.errors import ConfigError

from .effects import Effect, parse_effects

_TOP_KEYS = {"motor_inertia", "viscous", "coulomb", "static", "sensors", "integration", "seed", "effects"}


@dataclass(frozen=True, eq=False)
class SimTruth:
    """True drive-side parameters of the simulated arm (see the module docstring for keys and units)."""
    motor_inertia: np.ndarray          # J_a (n,), kg*m^2
    viscous: np.ndarray                # B (n,), N*m*s/rad
    coulomb: np.ndarray                # f_c (n,), N*m
    static: np.ndarray                 # f_s (n,), N*m
    current_noise_std: np.ndarray      # (n,), A
    substeps: int = 2
    seed: int = 0
    effects: tuple[Effect, ...] = ()
    source: str | None = None
    raw: dict = field(default_factory=dict)

    @property
    def n(self) -> int:
        return len(self.motor_inertia)

    def replace(self, **changes) -> "SimTruth":
        """A copy with some fields changed (arrays are converted to float arrays)."""
        for k, v in list(changes.items()):
            if k in ("motor_inertia", "viscous", "coulomb", "static", "current_noise_std"):
                changes[k] = np.broadcast_to(np.asarray(v, dtype=float), (self.n,)).copy()
        return dataclasses.replace(self, **changes)

    def without_friction(self) -> "SimTruth":
        """The same truth with B = f_c = f_s = 0 (conservative arm; energy checks)."""
        z = np.zeros(self.n)
        return self.replace(viscous=z, coulomb=z, static=z)


def _vec(d: dict, key: str, n: int, source, *, required: bool, positive=False, default=None) -> np.ndarray:
    """A per-drive list of sim_truth.yaml: finite and >= 0 (``positive``: > 0)."""
    return parse_vector(d, key, n, source, required=required, positive=positive, nonneg=True, default=default,
                        per="drive")


def _section(d: dict, name: str, known: tuple[str, ...], source) -> dict:
    """An optional sub-mapping of sim_truth.yaml whose keys must all be known."""
    sec = d.get(name) or {}
    if not isinstance(sec, dict):
        raise ConfigError(source, name, f"must be a mapping ({', '.join(known)})")
    bad = sorted(set(sec) - set(known))
    if bad:
        raise ConfigError(source, f"{name}.{bad[0]}", f"unknown key (known: {', '.join(known)})")
    return sec


def parse_truth(d: Any, n: int, source: str | Path | None = None, joints: list[str] | None = None) -> SimTruth:
    """Validate a parsed sim_truth mapping for ``n`` drives; raise :class:`ConfigError` naming file and key."""
    if not isinstance(d, dict):
        raise ConfigError(source, None, f"must be a YAML mapping with the sim_truth keys, got {type(d).__name__}")
    unknown = sorted(set(d) - _TOP_KEYS)
    if unknown:
        raise ConfigError(source, unknown[0], f"unknown key (known: {', '.join(sorted(_TOP_KEYS))})")
    ja = _vec(d, "motor_inertia", n, source, required=True, positive=True)
    b = _vec(d, "viscous", n, source, required=True)
    fc = _vec(d, "coulomb", n, source, required=True)
    fs = _vec(d, "static", n, source, required=True)
    if np.any(fs < fc):
        raise ConfigError(source, "static", f"breakaway friction must be >= coulomb on every drive, got static "
                                            f"{fs.tolist()} < coulomb {fc.tolist()}")
    sensors = _section(d, "sensors", ("current_noise_std",), source)
    noise = _vec(sensors, "sensors.current_noise_std", n, source, required=False, default=0.0)
    integ = _section(d, "integration", ("substeps",), source)
    substeps = integ.get("substeps", 2)
    if isinstance(substeps, bool) or not isinstance(substeps, int) or substeps < 1:
        raise ConfigError(source, "integration.substeps", f"must be an integer >= 1, got {substeps!r}")
    seed = d.get("seed", 0)
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ConfigError(source, "seed", f"must be an integer >= 0, got {seed!r}")
    effects = parse_effects(d.get("effects") or [], n, source, joints=joints)
    return SimTruth(motor_inertia=ja, viscous=b, coulomb=fc, static=fs, current_noise_std=noise,
                    substeps=substeps, seed=seed, effects=tuple(effects),
                    source=str(source) if source is not None else None, raw=d)


def load_truth(robot_or_path, n: int | None = None) -> SimTruth:
    """Load ``sim_truth.yaml``: from a :class:`js2spec.robot.RobotConfig` (its ``sim_truth_path``) or a path.

    ``n`` (number of drives) is taken from the robot; give it when passing a bare path.
    """
    joints = None
    if hasattr(robot_or_path, "drives"):
        robot = robot_or_path
        n = robot.drives.n
        joints = list(robot.drives.joints)
        path = robot.sim_truth_path
        if path is None:
            raise ConfigError(Path(robot.folder) / "sim_truth.yaml", None,
                              "file not found (the simulator needs the robot's true drive parameters)")
    else:
        path = robot_or_path
        if n is None:
            raise ConfigError(path, None, "load_truth(path) needs n, the number of drives")
    from js2spec.files import load_yaml
    path = Path(path)
    d = load_yaml(path, "simulator truth file")
    return parse_truth(d, n, path, joints=joints)
