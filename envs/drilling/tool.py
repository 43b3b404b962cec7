"""The drill as a cantilever (Li et al. 2023 §2.2.2)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class CantileverTool:
    """A straight drill clamped in the chuck, loaded at its tip.

    Lateral stiffness ``3 E I / l**3`` with ``I = π d_eff**4 / 64`` (a fluted drill bends like a
    solid rod of diameter ``d_eff ≈ 0.85 D``); axial stiffness ``E A / l``. Frame: the tool frame,
    z along the drill axis.
    """

    diameter_m: float = 1.5e-3
    """Nominal drill diameter D (m)."""
    stickout_m: float = 0.036
    """Free length from the chuck to the tip, l (m)."""
    youngs_modulus_pa: float = 210e9
    """Young's modulus E of tool steel (Pa)."""
    poisson_ratio: float = 0.3
    """Poisson's ratio ν (used for the shear modulus G = E / 2(1 + ν))."""
    effective_diameter_ratio: float = 0.85
    """d_eff / D: the flutes remove material, the core bends like a smaller rod."""

    @property
    def second_moment_m4(self) -> float:
        """Area moment of inertia I (m^4) of the effective section."""
        d_eff = self.effective_diameter_ratio * self.diameter_m
        return math.pi * d_eff**4 / 64.0

    @property
    def area_m2(self) -> float:
        """Effective cross-section area A (m^2)."""
        d_eff = self.effective_diameter_ratio * self.diameter_m
        return math.pi * d_eff**2 / 4.0

    @property
    def lateral_stiffness_n_m(self) -> float:
        """Tip lateral stiffness 3EI/l³ (N/m)."""
        return 3.0 * self.youngs_modulus_pa * self.second_moment_m4 / self.stickout_m**3

    @property
    def axial_stiffness_n_m(self) -> float:
        """Axial stiffness EA/l (N/m)."""
        return self.youngs_modulus_pa * self.area_m2 / self.stickout_m

    @property
    def shear_modulus_pa(self) -> float:
        """Shear modulus G = E / (2 (1 + ν)) (Pa)."""
        return self.youngs_modulus_pa / (2.0 * (1.0 + self.poisson_ratio))

    def compliance_tool_m_n(self) -> np.ndarray:
        """Tip translational compliance in the tool frame, diag(1/k_lat, 1/k_lat, 1/k_ax) (m/N)."""
        k_lat = self.lateral_stiffness_n_m
        return np.diag([1.0 / k_lat, 1.0 / k_lat, 1.0 / self.axial_stiffness_n_m])

    def tip_deflection_m(self, force_tool_n: np.ndarray) -> np.ndarray:
        """Tip deflection (m, tool frame) under a tip force (N, tool frame)."""
        return self.compliance_tool_m_n() @ np.asarray(force_tool_n, dtype=float)
