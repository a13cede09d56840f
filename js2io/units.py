"""The ONE place where CiA 402 device units become SI (and back).

Position actual (0x6064): encoder increments -> motor rad. Target/actual torque (0x6071/0x6077): per-mille of the
motor rated torque 0x6076 -> N*m. Current actual (0x6078): per-mille of the rated current 0x6075 -> A.
Target velocity (0x60FF): increments per second <-> motor rad/s.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from js2spec.errors import ConfigError


@dataclass(frozen=True)
class Scaling:
    counts_per_rev: np.ndarray   # (n,)
    rated_torque: np.ndarray     # N*m  (0x6076 is mN*m)
    rated_current: np.ndarray    # A    (0x6075 is mA)
    torque_constant: np.ndarray  # N*m/A

    @classmethod
    def from_drives(cls, drives) -> "Scaling":
        n = drives.n
        cpr = np.asarray(drives.encoder_counts_per_rev, dtype=float)
        if drives.rated_torque is None or drives.rated_current is None:
            raise ConfigError(drives.source, "rated_torque", "rated_torque and rated_current are required for CiA 402 "
                              "drives (they scale torque and current, objects 0x6076/0x6075); add them")
        rt = np.asarray(drives.rated_torque, dtype=float)
        rc = np.asarray(drives.rated_current, dtype=float)
        if np.any(cpr <= 0):
            raise ConfigError(drives.source, "encoder_counts_per_rev", "must be > 0 for every drive to run trials")
        if len(cpr) != n or len(rt) != n or len(rc) != n:
            raise ConfigError(drives.source, "rated_torque", "encoder_counts_per_rev/rated_torque/rated_current need one "
                              "entry per drive")
        return cls(cpr, rt, rc, np.asarray(drives.torque_constant, dtype=float))

    # --- device -> SI
    def position_si(self, counts) -> np.ndarray:
        return np.asarray(counts, dtype=float) * (2.0 * math.pi) / self.counts_per_rev

    def torque_si(self, permille) -> np.ndarray:
        return np.asarray(permille, dtype=float) * self.rated_torque / 1000.0

    def current_si(self, permille) -> np.ndarray:
        return np.asarray(permille, dtype=float) * self.rated_current / 1000.0

    def velocity_si(self, counts_per_s) -> np.ndarray:
        return np.asarray(counts_per_s, dtype=float) * (2.0 * math.pi) / self.counts_per_rev

    # --- SI -> device (rounded to the integer the object holds)
    def torque_permille(self, tau) -> np.ndarray:
        return np.rint(np.asarray(tau, dtype=float) * 1000.0 / self.rated_torque).astype(np.int64)

    def torque_limit_permille(self, tau_limit) -> np.ndarray:
        """0x6072 for a limit in N*m: rounded DOWN so the drive limit never exceeds the configured one."""
        return np.floor(np.asarray(tau_limit, dtype=float) * 1000.0 / self.rated_torque + 1e-9).astype(np.int64)

    def current_permille(self, amps) -> np.ndarray:
        return np.rint(np.asarray(amps, dtype=float) * 1000.0 / self.rated_current).astype(np.int64)

    def velocity_counts(self, rad_s) -> np.ndarray:
        return np.rint(np.asarray(rad_s, dtype=float) * self.counts_per_rev / (2.0 * math.pi)).astype(np.int64)

    def position_counts(self, rad) -> np.ndarray:
        return np.rint(np.asarray(rad, dtype=float) * self.counts_per_rev / (2.0 * math.pi)).astype(np.int64)

    def rated_torque_mnm(self) -> np.ndarray:
        return np.rint(self.rated_torque * 1000.0).astype(np.int64)

    def rated_current_ma(self) -> np.ndarray:
        return np.rint(self.rated_current * 1000.0).astype(np.int64)
