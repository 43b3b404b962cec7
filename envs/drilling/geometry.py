"""Twist-drill point geometry (Li et al. 2023, Fig. 2; Table 2)."""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class DrillGeometry:
    """Geometry of a two-lip twist drill point.

    Tool frame: z along the drill axis toward the bone (the feed direction), origin at the tip.
    A lip point at radius ``r`` sits ``r * cot(kappa)`` behind the tip along the axis.
    """

    diameter_m: float = 1.5e-3
    """Drill diameter D (m). Li Table 2: 1.5 mm."""
    point_angle_deg: float = 118.0
    """Full point angle 2κ (deg); 118° is the standard twist-drill point."""
    helix_angle_deg: float = 28.0
    """Helix angle ψ (deg). Li Table 2: 28°."""
    web_ratio: float = 0.18
    """Web half-thickness w over radius R: the chisel edge spans r < w."""
    n_lips: int = 2
    """Number of cutting lips. Li Table 2: 2."""

    @property
    def radius_m(self) -> float:
        """Drill radius R (m)."""
        return 0.5 * self.diameter_m

    @property
    def kappa_rad(self) -> float:
        """Point half-angle κ (rad)."""
        return math.radians(0.5 * self.point_angle_deg)

    @property
    def cot_kappa(self) -> float:
        """Cot κ: axial set-back of a lip point per metre of radius."""
        return 1.0 / math.tan(self.kappa_rad)

    @property
    def web_radius_m(self) -> float:
        """Chisel-edge half-length w (m)."""
        return self.web_ratio * self.radius_m

    def full_engagement_depth_m(self, beta_rad: float) -> float:
        """Tip depth past the surface (m) at which both lips are engaged over the whole revolution.

        ``R (cot κ + tan|β|)``: the end of the entry (Li's stage 4 begins).
        """
        return self.radius_m * (self.cot_kappa + math.tan(abs(beta_rad)))

    def chip_thickness_m(self, feed_m_s: float, spindle_rpm: float) -> float:
        """Uncut chip thickness per lip h = c / (N n) · sin κ (m)."""
        rev_per_s = spindle_rpm / 60.0
        return feed_m_s / (self.n_lips * rev_per_s) * math.sin(self.kappa_rad)
