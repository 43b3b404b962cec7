"""Sensor models: what the real cell measures, with its noise and resolution.

All randomness comes from the generator handed in (the env's ``np_random``), so a seeded reset
reproduces every sample bit for bit.
"""

from __future__ import annotations

import math

import numpy as np

from drillgym.envs.constants import FT_RESOLUTION, FT_TORQUE_NOISE_ARM_M


class ForceTorqueSensor:
    """A 6-axis F/T sensor at the flange (ATI Mini40-like), tared before contact.

    Reads the external wrench on the tool, in the sensor frame (axes of the tool frame: z along the
    drill toward the bone): forces (N) and torques about the sensor origin (N·m). Gaussian noise of
    ``noise_n`` std on each force axis (``noise_n · 5 mm`` on torques), then quantised to the sensor's
    resolution (0.01 N in Fx/Fy, 0.02 N in Fz).
    """

    def __init__(self, noise_n: float, rng: np.random.Generator) -> None:
        self.noise_n = noise_n
        self.rng = rng
        self._noise_std = np.array([noise_n] * 3 + [noise_n * FT_TORQUE_NOISE_ARM_M] * 3)

    def sample(self, wrench_sensor: np.ndarray) -> np.ndarray:
        """One reading (6,) of the true wrench ``(F N, τ N·m)`` in the sensor frame."""
        noisy = wrench_sensor + self._noise_std * self.rng.standard_normal(6) if self.noise_n > 0 else wrench_sensor
        return np.round(noisy / FT_RESOLUTION) * FT_RESOLUTION

    def sample_block(self, wrenches_sensor: np.ndarray) -> np.ndarray:
        """Readings (n, 6) of n true wrenches, one noise draw per sample (same as n calls to sample)."""
        w = np.asarray(wrenches_sensor, dtype=float)
        if self.noise_n > 0:
            w = w + self._noise_std * self.rng.standard_normal(w.shape)
        w = np.rint(w / FT_RESOLUTION)  # what np.round does for 0 decimals, without its Python wrapper
        w *= FT_RESOLUTION
        return w


class PositionTracker:
    """An optical tracker's marker position, with Gaussian noise of ``noise_m`` std per axis (m)."""

    def __init__(self, noise_m: float, rng: np.random.Generator) -> None:
        self.noise_m = noise_m
        self.rng = rng

    def sample(self, position_m: np.ndarray) -> np.ndarray:
        """One reading (3,) of the true marker position (m, any fixed frame)."""
        if self.noise_m <= 0:
            return np.asarray(position_m, dtype=float).copy()
        return position_m + self.noise_m * self.rng.standard_normal(3)


def latest_sample_time_s(t_s: float, rate_hz: float) -> float:
    """Time stamp (s) of the newest sample of a stream at ``rate_hz`` started at t = 0."""
    return math.floor(t_s * rate_hz + 1e-9) / rate_hz
