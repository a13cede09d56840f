"""The model file, ``model.yaml`` — written by identification, extended by diagnosis, loaded by the simulator
and by users. Whatever reads it reads it through :func:`load_model`.

Required keys (motor side, SI units, per-motor lists in drive order):
``joints``, ``friction: {static, coulomb, viscous}`` (N*m, N*m, N*m*s/rad), ``motor_inertia`` (kg*m^2),
``base_parameters: {names, values, std}``, ``validation: {rms, nrms}``.
The identified URDF (``robot_identified.urdf``) sits beside it (or the key ``urdf`` names it).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .errors import ConfigError


def friction_hold_limit(f_static: np.ndarray) -> np.ndarray:
    """The most torque a model's friction holds at rest, per motor (the model's side and units): its f_s (eq. 2-3)
    where the static breakaway test identified one, no limit (inf) where the model has none (the simultaneous
    method, a plain recording with no trial labels). The one rule the diagnosis' prediction
    (:func:`diagnosis.residual.hold_at_rest`) and hil_sim's replay (:func:`hil_sim.replay.inverse_replay`) hold by.

    A model without f_s does not know how much its friction holds: clipping there at f_c (until stop 44) made the
    prediction wrong at every rest where the arm's stiction held more than f_c. The drive's torque climbs over f_c
    before the axis breaks away, the clipped prediction does not, and the torque filter spread that step into the
    moving rows beside it as a ringing burst: on a clean recording of the foreign simulator (Karnopp stiction, no
    static test; twin 8) 81-88 % of four motors' scored residual lay within 50 ms of a rest, on 8-9 % of the rows,
    and the search named plays, coggings and asymmetries on it."""
    f_static = np.asarray(f_static, float)
    return np.where(np.isfinite(f_static), f_static, np.inf)


@dataclass(frozen=True, eq=False)
class IdentifiedModel:
    path: Path
    joints: list[str]
    friction_static: np.ndarray      # f_s, N*m motor side (NaN: not identified, simultaneous method)
    friction_coulomb: np.ndarray     # f_c, N*m motor side
    friction_viscous: np.ndarray     # B, N*m*s/rad motor side
    motor_inertia: np.ndarray        # J_a, kg*m^2
    base_names: list[str]
    base_values: np.ndarray
    base_std: np.ndarray
    urdf_path: Path | None
    raw: dict = field(default_factory=dict)
    # Bs of the extra friction Bs sgn(v) sqrt|v| (N*m*(s/rad)^0.5, the side of ``viscous``); zeros when the model
    # has none (``friction.sqrt_viscous`` is written only when cross-validation kept it)
    friction_sqrt_viscous: np.ndarray | None = None

    @property
    def n(self) -> int:
        return len(self.joints)

    @property
    def urdf_text(self) -> str:
        if self.urdf_path is None or not self.urdf_path.is_file():
            raise ConfigError(self.path, "urdf", "the identified URDF beside model.yaml is missing")
        from .files import read_text
        return read_text(self.urdf_path, "identified URDF")

    @property
    def inputs(self) -> list[dict]:
        """model.yaml's ``inputs``: the recordings the model was identified (and validated) on."""
        return list(self.raw.get("inputs") or [])

    @staticmethod
    def is_recording(item: dict, log) -> bool:
        """Whether ``log`` (a read js2 log) is the recording an ``inputs`` item names: the same file (``sha256``) or
        the same data written again (``data_sha256``: imported twice, the file's metadata differs)."""
        return bool((item.get("sha256") and item["sha256"] == log.sha256)
                    or (item.get("data_sha256") and item["data_sha256"] == log.data_sha256))

    def is_input(self, log) -> bool:
        """Whether ``log`` is one of the model's own recordings (:meth:`is_recording` of any ``inputs`` item)."""
        return any(self.is_recording(item, log) for item in self.inputs)

    def recording_mismatch(self, drives) -> tuple[str, str] | None:
        """Why a recording with these ``drives`` (``drives.yaml`` of a js2 log) cannot be compared with this model,
        or None: ``("joints", text)`` when its joints are not the model's, ``("torque_side", text)`` when it
        measured torque on the other side of the gears than the model was identified on. The text names both
        sides; each caller adds its own advice and error class (diagnosis, replay)."""
        if list(self.joints) != list(drives.joints):
            return "joints", f"the recording's joints {list(drives.joints)} are not the model's {list(self.joints)}"
        side = str(drives.torque_side)
        model_side = str(self.raw.get("torque_side", side))
        if model_side != side:
            return "torque_side", f"torque_side is {side!r} but {self.path} was identified on the {model_side!r} side"
        return None

    @property
    def torque_offset(self) -> np.ndarray:
        """Constant torque offsets (N*m, on the model's torque side) of the exported model: ``torque_offset`` of
        model.yaml (those of the physically consistent parameters the URDF holds); a model without that key: its
        base parameters ``off_<k>``; else zeros. (The base values belong to the unconstrained fit: with the URDF's
        parameters they can be N*m off — 2.7 N*m on a real KUKA shoulder.)"""
        n = self.n
        raw = self.raw.get("torque_offset")
        if isinstance(raw, list) and len(raw) == n:
            try:
                return np.nan_to_num(np.asarray([np.nan if v is None else v for v in raw], float))
            except (TypeError, ValueError):
                raise ConfigError(self.path, "torque_offset", f"must be a list of {n} numbers") from None
        off = np.zeros(n)
        for name, v in zip(self.base_names, self.base_values):
            if name.startswith("off_") and name[4:].isdigit() and 1 <= int(name[4:]) <= n and np.isfinite(v):
                off[int(name[4:]) - 1] = v
        return off

    @property
    def unmodelled(self) -> list[dict]:
        """Effects added by diagnosis (``unmodelled:`` list), empty for a plain identified model."""
        return list(self.raw.get("unmodelled") or [])


def _vec(d: dict, key: str, n: int, path, name: str, nullable: bool = False) -> np.ndarray:
    if key not in d:
        raise ConfigError(path, name, "missing")
    try:
        vals = d[key]
        if nullable and isinstance(vals, list):
            vals = [np.nan if v is None else v for v in vals]
        arr = np.asarray(vals, dtype=float)
    except (TypeError, ValueError):
        raise ConfigError(path, name, "must be a list of numbers") from None
    if arr.shape != (n,):
        raise ConfigError(path, name, f"must have one entry per joint ({n}), got shape {arr.shape}")
    if not np.all(np.isfinite(arr) | (nullable & np.isnan(arr))):
        raise ConfigError(path, name, "contains NaN or infinite values")
    return arr


def load_model(path: str | Path) -> IdentifiedModel:
    """Load ``model.yaml`` (or the folder holding it)."""
    path = Path(path)
    if path.is_dir():
        path = path / "model.yaml"
    if not path.is_file():
        raise ConfigError(path, None, "model file not found (js2-identify writes OUTDIR/model.yaml)")
    from .files import load_yaml
    d = load_yaml(path, "model file")
    if not isinstance(d, dict):
        raise ConfigError(path, None, "must be a YAML mapping")
    joints = d.get("joints")
    if not isinstance(joints, list) or not joints:
        raise ConfigError(path, "joints", "missing or not a list of joint names")
    n = len(joints)
    fr = d.get("friction")
    if not isinstance(fr, dict):
        raise ConfigError(path, "friction", "missing (mapping with static, coulomb, viscous)")
    # static friction comes from the sequential static test; a model from the simultaneous method has none (null)
    fs = _vec(fr, "static", n, path, "friction.static", nullable=True)
    fc = _vec(fr, "coulomb", n, path, "friction.coulomb")
    fv = _vec(fr, "viscous", n, path, "friction.viscous")
    fsq = (_vec(fr, "sqrt_viscous", n, path, "friction.sqrt_viscous", nullable=True) if fr.get("sqrt_viscous")
           is not None else np.zeros(n))
    fsq = np.nan_to_num(fsq)
    ja = _vec(d, "motor_inertia", n, path, "motor_inertia")
    bp = d.get("base_parameters")
    if not isinstance(bp, dict) or not {"names", "values"} <= bp.keys():
        raise ConfigError(path, "base_parameters", "missing (mapping with names, values, std)")
    names = list(bp["names"])
    values = np.asarray(bp["values"], dtype=float)
    std = np.asarray(bp.get("std", [np.nan] * len(names)), dtype=float)
    if len(names) != len(values) or len(std) != len(values):
        raise ConfigError(path, "base_parameters", "names, values and std must have the same length")
    urdf = d.get("urdf", "robot_identified.urdf")
    urdf_path = (path.parent / urdf) if urdf else None
    return IdentifiedModel(path=path, joints=list(joints), friction_static=fs, friction_coulomb=fc,
                           friction_viscous=fv, motor_inertia=ja, base_names=names, base_values=values,
                           base_std=std, urdf_path=urdf_path, raw=d, friction_sqrt_viscous=fsq)
