"""What a CiA 402 drive sees of its motor: encoder counts and the current read-back.

* encoder: ``counts = round(theta_m * cpr / 2 pi)`` (int64), position = ``counts * 2 pi / cpr`` (0x6064, quantised
  to one count; a drive with ``encoder_counts_per_rev: 0`` reports the exact angle and 0 counts);
* current: the drive's current loop is taken as ideal, ``I = tau_m / k_t``; the read-back (0x6078) adds white
  gaussian noise (``sim_truth.yaml`` ``sensors.current_noise_std``) and is quantised to one per-mille of
  ``rated_current`` (when given);
* torque: ``tau_motor = k_t I_measured`` (what identification uses as eq. 1's ``tau_m``).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(eq=False, slots=True)
class SensorReading:
    encoder_counts: np.ndarray    # int64 (n,), counts since reset position 0
    motor_position: np.ndarray    # rad (n,), motor shaft, quantised to one count
    motor_current: np.ndarray     # A (n,), noisy, quantised to 1/1000 rated_current
    tau_motor: np.ndarray         # N*m (n,), torque_constant * motor_current
    t: float = 0.0                # s, plant time of the reading


class Sensors:
    """Quantisation and noise of one drive set (model: ``DrivesConfig``; noise: ``SimTruth``)."""

    def __init__(self, drives, current_noise_std, rng: np.random.Generator):
        cpr = np.asarray(drives.encoder_counts_per_rev, dtype=float)
        self.exact = cpr <= 0
        cpr_safe = np.where(self.exact, 1.0, cpr)
        self.counts_per_rad = cpr_safe / (2.0 * np.pi)
        self.rad_per_count = 2.0 * np.pi / cpr_safe
        self.torque_constant = np.asarray(drives.torque_constant, dtype=float)
        self.inv_torque_constant = 1.0 / self.torque_constant
        rc = drives.rated_current
        self.current_lsb = None if rc is None else np.asarray(rc, dtype=float) / 1000.0
        self.noise_std = np.asarray(current_noise_std, dtype=float)
        self.any_noise = bool(np.any(self.noise_std > 0))
        self.any_exact = bool(np.any(self.exact))
        self.rng = rng

    def read(self, q_motor: np.ndarray, tau_motor: np.ndarray, t: float = 0.0) -> SensorReading:
        counts = np.rint(q_motor * self.counts_per_rad).astype(np.int64)
        pos = counts * self.rad_per_count
        if self.any_exact:
            counts[self.exact] = 0
            pos[self.exact] = q_motor[self.exact]
        current = tau_motor * self.inv_torque_constant
        if self.any_noise:
            current = current + self.noise_std * self.rng.standard_normal(len(current))
        if self.current_lsb is not None:
            current = np.rint(current / self.current_lsb) * self.current_lsb
        return SensorReading(counts, pos, current, self.torque_constant * current, t)
