"""Reality: the F/T sensor sits on a mount with a lateral and an axial mode of their own."""

from __future__ import annotations

import math

import numpy as np

from drillgym.envs.constants import PHYSICS_DT_S
from drillgym.envs.effects.base import EffectHost, Param
from drillgym.eval.diagnosis.reality.base import RealityEffect

SUBSTEPS = 20
"""Integration steps of the modes per F/T sample (semi-implicit Euler, the wrench held between samples)."""


class MountResonance(RealityEffect):
    """Two mount modes: the lateral axes (Fx, Fy, Tx, Ty) ring at one frequency, the axial ones (Fz, Tz) at another.

    Each axis reads ``x`` of ``x'' + 2ζω x' + ω² x = ω² W``, integrated in :data:`SUBSTEPS` semi-implicit Euler
    steps per sample. The candidate (``ft_resonance``) has the same two groups of axes, its modes discretised
    exactly for a wrench held over each sample, and a share of the reading through them (here the whole).
    """

    name = "mount_resonance"
    summary = "F/T readings through a lateral and an axial mount mode"
    explains = "ft_resonance"
    params = (
        Param("freq_xy_hz", 5.0, 45.0, 20.0, "lateral mode (Hz)"),
        Param("freq_z_hz", 5.0, 45.0, 20.0, "axial mode (Hz)"),
        Param("damping", 0.0, 0.7, 0.0, "damping ratio of both modes (0: no mount, the reading is the wrench)"),
    )
    channels = frozenset({"force", "torque"})

    def attach(self, env: EffectHost) -> None:
        """Both modes at rest."""
        self.x = np.zeros(6)
        self.v = np.zeros(6)

    def sensor_wrenches(self, env: EffectHost, wrenches: np.ndarray, t_s: np.ndarray) -> np.ndarray:
        """Integrate the modes over each sample with its wrench held."""
        zeta = self.values["damping"]
        w_in = np.asarray(wrenches, dtype=float)
        if zeta == 0.0:
            return w_in
        f = np.array([self.values["freq_xy_hz"]] * 2 + [self.values["freq_z_hz"]] + [self.values["freq_xy_hz"]] * 2)
        omega = 2.0 * math.pi * np.append(f, self.values["freq_z_hz"])
        h = PHYSICS_DT_S / SUBSTEPS
        out = np.empty_like(w_in)
        for k, w in enumerate(w_in):
            for _ in range(SUBSTEPS):
                self.v += h * (omega * omega * (w - self.x) - 2.0 * zeta * omega * self.v)
                self.x += h * self.v
            out[k] = self.x
        return out

    def candidate_values(self) -> dict[str, float] | None:
        """The candidate's two modes, the whole reading through them."""
        v = self.values
        return {
            "amplitude": 1.0,
            "freq_lateral_hz": v["freq_xy_hz"],
            "freq_axial_hz": v["freq_z_hz"],
            "damping": v["damping"],
        }
