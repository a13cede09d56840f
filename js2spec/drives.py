"""The drive and transmission file, ``drives.yaml`` (js2 log spec v1, "drives.yaml keys").

Spec keys (SI, lists in joint order): ``joints``, ``gear_ratio_matrix`` (K: q_joint = K q_motor + joint_offset),
``torque_constant`` (N*m/A), ``encoder_counts_per_rev``, ``rated_torque`` (N*m, optional), ``rated_current``
(A, optional), ``joint_offset`` (rad, optional), ``torque_side`` (``motor`` | ``joint``).

Extras used by acquisition and the simulated drives (optional for readers of logs):
``can: {node_ids, cycle_hz, heartbeat_ms}`` and ``limits: {torque (N*m motor side), position_min/position_max
(rad joint side), velocity (rad/s motor side)}``.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from .errors import ConfigError

SPEC_KEYS = ("joints", "gear_ratio_matrix", "torque_constant", "encoder_counts_per_rev", "rated_torque",
             "rated_current", "joint_offset", "torque_side")


@dataclass(frozen=True, eq=False)
class DrivesConfig:
    """Drive and transmission data of an arm, in SI units, arrays in drive (= joint list) order."""

    joints: list[str]
    gear_ratio_matrix: np.ndarray          # K (n, n): q_joint = K @ q_motor + joint_offset
    torque_constant: np.ndarray            # N*m/A
    encoder_counts_per_rev: np.ndarray     # int, 0 = unknown
    rated_torque: np.ndarray | None        # N*m (CiA 402 0x6076)
    rated_current: np.ndarray | None       # A (CiA 402 0x6075)
    joint_offset: np.ndarray               # rad
    torque_side: str = "motor"
    node_ids: list[int] | None = None
    cycle_hz: float | None = None
    heartbeat_ms: float | None = None
    torque_limit: np.ndarray | None = None     # N*m motor side
    position_min: np.ndarray | None = None     # rad joint side
    position_max: np.ndarray | None = None     # rad joint side
    velocity_limit: np.ndarray | None = None   # rad/s motor side
    raw: dict = field(default_factory=dict)
    source: str | None = None

    @property
    def n(self) -> int:
        return len(self.joints)

    @property
    def K(self) -> np.ndarray:  # noqa: N802 - the paper's name
        return self.gear_ratio_matrix

    @property
    def K_inv(self) -> np.ndarray:  # noqa: N802
        return np.linalg.inv(self.gear_ratio_matrix)

    def joint_from_motor(self, q_motor: np.ndarray) -> np.ndarray:
        """q_joint = K q_motor + joint_offset; works on (n,) or (N, n) arrays."""
        q_motor = np.asarray(q_motor, dtype=float)
        return q_motor @ self.gear_ratio_matrix.T + self.joint_offset

    def motor_from_joint(self, q_joint: np.ndarray) -> np.ndarray:
        """q_motor = K^-1 (q_joint - joint_offset); works on (n,) or (N, n) arrays."""
        q_joint = np.asarray(q_joint, dtype=float)
        return (q_joint - self.joint_offset) @ self.K_inv.T

    def joint_velocity_from_motor(self, dq_motor: np.ndarray) -> np.ndarray:
        return np.asarray(dq_motor, dtype=float) @ self.gear_ratio_matrix.T

    def joint_torque_from_motor(self, tau_motor: np.ndarray) -> np.ndarray:
        """tau_joint = K^-T tau_motor (power balance: tau_motor = K^T tau_joint, eq. 1)."""
        return np.asarray(tau_motor, dtype=float) @ self.K_inv

    def motor_torque_from_joint(self, tau_joint: np.ndarray) -> np.ndarray:
        """tau_motor = K^T tau_joint (eq. 1)."""
        return np.asarray(tau_joint, dtype=float) @ self.gear_ratio_matrix

    def to_dict(self) -> dict:
        """The mapping written to ``drives.yaml`` (spec keys first, then the extras that are set)."""
        d: dict[str, Any] = {
            "joints": list(self.joints),
            "gear_ratio_matrix": self.gear_ratio_matrix.tolist(),
            "torque_constant": self.torque_constant.tolist(),
            "encoder_counts_per_rev": [int(c) for c in self.encoder_counts_per_rev],
        }
        if self.rated_torque is not None:
            d["rated_torque"] = self.rated_torque.tolist()
        if self.rated_current is not None:
            d["rated_current"] = self.rated_current.tolist()
        d["joint_offset"] = self.joint_offset.tolist()
        d["torque_side"] = self.torque_side
        can = {k: v for k, v in (("node_ids", self.node_ids), ("cycle_hz", self.cycle_hz),
                                 ("heartbeat_ms", self.heartbeat_ms)) if v is not None}
        if can:
            d["can"] = can
        limits = {k: v.tolist() for k, v in (("torque", self.torque_limit), ("position_min", self.position_min),
                                            ("position_max", self.position_max),
                                            ("velocity", self.velocity_limit)) if v is not None}
        if limits:
            d["limits"] = limits
        return d

    def to_yaml(self) -> str:
        return yaml.safe_dump(self.to_dict(), sort_keys=False, default_flow_style=None)


def motor_rest_speed(min_speed_joint: float, gear_ratio_matrix) -> np.ndarray:
    """Each motor's rest speed (rad/s at the motor) for a rest speed ``min_speed_joint`` given at the joints
    (rad/s): min_speed / max_j |K_ji|, the motor speed at which the joint it drives fastest turns at min_speed. So
    one joint-side number suits a 1:100 harmonic drive (0.01 rad/s at the joint: 1 rad/s at the motor) and a direct
    drive alike. Below it friction holds the applied torque up to f_s (eq. 2-3): the diagnosis leaves those
    samples out and predicts the held torque there, and ``hil_sim``'s replay holds them the same way."""
    return float(min_speed_joint) / np.max(np.abs(np.asarray(gear_ratio_matrix, dtype=float)), axis=0)


def at_rest(speed: np.ndarray, rest_speed: np.ndarray) -> np.ndarray:
    """Where each axis is at rest: |speed| below its ``rest_speed`` (e.g. :func:`motor_rest_speed`), element-wise
    over (N, n) or (n,) speeds; a NaN speed (a lost sample) counts as 0, at rest."""
    return np.abs(np.nan_to_num(speed)) < rest_speed


def parse_vector(d: dict, key: str, n: int, source, *, required: bool, positive: bool = False,
                 nonneg: bool = False, default=None, integer: bool = False, per: str = "joint") -> np.ndarray | None:
    """One per-joint list of a config mapping, validated; errors name ``source`` and ``key``.

    ``key`` may be dotted (``limits.torque``): the last part is looked up in ``d``, the whole names it in errors.
    A single number stands for all ``n`` entries. Missing and not ``required`` gives ``default`` broadcast (or None).
    """
    name = key.split(".")[-1]
    if name not in d or d[name] is None:
        if required:
            raise ConfigError(source, key, f"missing (a list of {n} numbers, one per {per})")
        return None if default is None else np.full(n, default, dtype=float)
    v = d[name]
    if isinstance(v, bool):
        raise ConfigError(source, key, f"must be numbers, got {v!r}")
    if isinstance(v, (int, float)):
        v = [v] * n
    try:
        arr = np.asarray(v, dtype=float)
    except (TypeError, ValueError):
        raise ConfigError(source, key, f"must be a list of {n} numbers, got {v!r}") from None
    if arr.shape != (n,):
        raise ConfigError(source, key, f"must have one entry per {per} ({n}), got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ConfigError(source, key, "contains NaN or infinite values")
    if positive and np.any(arr <= 0):
        raise ConfigError(source, key, f"must be > 0, got {arr.tolist()}")
    if nonneg and np.any(arr < 0):
        raise ConfigError(source, key, f"must be >= 0, got {arr.tolist()}")
    if integer:
        if np.any(arr != np.round(arr)):
            raise ConfigError(source, key, f"must be integers, got {arr.tolist()}")
        return arr.astype(np.int64)
    return arr


def parse_drives(d: Any, source: str | Path | None = None) -> DrivesConfig:
    """Validate a parsed ``drives.yaml`` mapping; raise :class:`ConfigError` naming ``source`` and the key."""
    if not isinstance(d, dict):
        raise ConfigError(source, None, f"must be a YAML mapping with the drives.yaml keys, got {type(d).__name__}")
    joints = d.get("joints")
    if not isinstance(joints, list) or not joints or not all(isinstance(j, str) for j in joints):
        raise ConfigError(source, "joints", "missing or not a list of joint names")
    if len(set(joints)) != len(joints):
        raise ConfigError(source, "joints", f"duplicate joint names in {joints}")
    n = len(joints)
    if "gear_ratio_matrix" not in d:
        raise ConfigError(source, "gear_ratio_matrix", f"missing (the {n}x{n} matrix K, q_joint = K q_motor)")
    try:
        K = np.asarray(d["gear_ratio_matrix"], dtype=float)
    except (TypeError, ValueError):
        raise ConfigError(source, "gear_ratio_matrix", "must be a list of numeric rows") from None
    if K.shape != (n, n):
        raise ConfigError(source, "gear_ratio_matrix", f"must be {n}x{n} (one row per joint), got shape {K.shape}")
    if not np.all(np.isfinite(K)):
        raise ConfigError(source, "gear_ratio_matrix", "contains NaN or infinite values")
    cond = np.linalg.cond(K)
    if not np.isfinite(cond) or cond > 1e12:
        raise ConfigError(source, "gear_ratio_matrix",
                          f"is singular (condition number {cond:.3g}): every joint needs a motor that moves it")
    torque_side = d.get("torque_side", "motor")
    if torque_side not in ("motor", "joint"):
        raise ConfigError(source, "torque_side", f"must be 'motor' or 'joint', got {torque_side!r}")
    kt = parse_vector(d, "torque_constant", n, source, required=True, positive=True)
    counts = parse_vector(d, "encoder_counts_per_rev", n, source, required=True, nonneg=True, integer=True)
    rated_torque = parse_vector(d, "rated_torque", n, source, required=False, positive=True)
    rated_current = parse_vector(d, "rated_current", n, source, required=False, positive=True)
    offset = parse_vector(d, "joint_offset", n, source, required=False, default=0.0)

    can = d.get("can") or {}
    if not isinstance(can, dict):
        raise ConfigError(source, "can", "must be a mapping (node_ids, cycle_hz, heartbeat_ms)")
    node_ids = can.get("node_ids")
    if node_ids is not None:
        if (not isinstance(node_ids, list) or len(node_ids) != n
                or not all(isinstance(i, int) and 1 <= i <= 127 for i in node_ids)):
            raise ConfigError(source, "can.node_ids", f"must be {n} CANopen node ids in 1..127, got {node_ids!r}")
        if len(set(node_ids)) != n:
            raise ConfigError(source, "can.node_ids", f"node ids must be distinct, got {node_ids}")
    cycle_hz = can.get("cycle_hz")
    if cycle_hz is not None and (not isinstance(cycle_hz, (int, float)) or cycle_hz <= 0):
        raise ConfigError(source, "can.cycle_hz", f"must be a positive number, got {cycle_hz!r}")
    heartbeat_ms = can.get("heartbeat_ms")
    if heartbeat_ms is not None and (not isinstance(heartbeat_ms, (int, float)) or heartbeat_ms <= 0):
        raise ConfigError(source, "can.heartbeat_ms", f"must be a positive number, got {heartbeat_ms!r}")

    limits = d.get("limits") or {}
    if not isinstance(limits, dict):
        raise ConfigError(source, "limits", "must be a mapping (torque, position_min, position_max, velocity)")
    torque_limit = parse_vector(limits, "limits.torque", n, source, required=False, positive=True)
    pmin = parse_vector(limits, "limits.position_min", n, source, required=False)
    pmax = parse_vector(limits, "limits.position_max", n, source, required=False)
    vel = parse_vector(limits, "limits.velocity", n, source, required=False, positive=True)
    if (pmin is None) != (pmax is None):
        raise ConfigError(source, "limits.position_min", "position_min and position_max go together")
    if pmin is not None and np.any(pmin >= pmax):
        raise ConfigError(source, "limits.position_min", "must be below limits.position_max on every joint")
    if torque_limit is not None and rated_torque is not None and np.any(torque_limit > 3.0 * rated_torque):
        raise ConfigError(source, "limits.torque", "is more than 3x rated_torque; check the units (N*m motor side)")

    return DrivesConfig(joints=list(joints), gear_ratio_matrix=K, torque_constant=kt,
                        encoder_counts_per_rev=counts, rated_torque=rated_torque, rated_current=rated_current,
                        joint_offset=offset, torque_side=torque_side, node_ids=node_ids,
                        cycle_hz=float(cycle_hz) if cycle_hz is not None else None,
                        heartbeat_ms=float(heartbeat_ms) if heartbeat_ms is not None else None,
                        torque_limit=torque_limit, position_min=pmin, position_max=pmax, velocity_limit=vel,
                        raw=d, source=str(source) if source is not None else None)


def parse_drives_yaml(text: str, source: str | Path | None = None) -> DrivesConfig:
    try:
        d = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise ConfigError(source, None, f"is not valid YAML ({str(exc).splitlines()[0]})") from None
    return parse_drives(d, source)


def load_drives(path: str | Path) -> DrivesConfig:
    from .files import read_text
    path = Path(path)
    return parse_drives_yaml(read_text(path, "drives.yaml"), path)
