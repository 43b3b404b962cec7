"""Scenario: the drilling experiment a user sets up, validated, with user units at the edge.

Keyword arguments are in the units people quote (mm, mm/s, deg, rpm); properties give SI values.
Defaults are Li et al. 2023's experiment: β 30°, 0.5 mm/s, 20,000 rpm, a 1.5 mm two-lip twist drill.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Any

from drillgym.envs.drilling.bone import BONE_PRESETS
from drillgym.envs.drilling.geometry import DrillGeometry
from drillgym.envs.errors import UserError

# name -> (low, high, inclusive_low); every numeric field is checked against its range.
RANGES: dict[str, tuple[float, float, bool]] = {
    "beta_deg": (-40.0, 40.0, True),
    "feed_mm_s": (0.0, 3.0, False),
    "spindle_rpm": (1000.0, 60000.0, True),
    "drill_diameter_mm": (0.5, 6.0, True),
    "stickout_mm": (10.0, 100.0, True),
    "depth_mm": (2.0, 30.0, True),
    "cortical_thickness_mm": (0.3, 40.0, True),
    "density_scale": (0.3, 3.0, True),
    "bone_variability": (0.0, 0.3, True),
    "ft_noise_n": (0.0, 2.0, True),
    "tracker_noise_mm": (0.0, 2.0, True),
    "latency_s": (0.0, 0.5, True),
    "servo_time_constant_s": (0.001, 0.5, True),
    "force_limit_n": (1.0, 500.0, True),
}


@dataclass(frozen=True)
class Scenario:
    """One drilling experiment. See the env docstring for the table of arguments."""

    beta_deg: float = 30.0
    feed_mm_s: float = 0.5
    spindle_rpm: float = 20000.0
    drill_diameter_mm: float = 1.5
    stickout_mm: float = 37.9
    depth_mm: float = 6.0
    cortical_thickness_mm: float = 8.0
    bone: str = "buffalo_femur"
    density_scale: float = 1.0
    bone_variability: float = 0.05
    ft_noise_n: float = 0.02
    tracker_noise_mm: float = 0.05
    latency_s: float = 0.014
    servo_time_constant_s: float = 0.02
    tracker: bool = True
    force_limit_n: float = 40.0

    def __post_init__(self) -> None:
        for name, (lo, hi, incl) in RANGES.items():
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise UserError(f"{name}={value!r} must be a number in {_range_text(lo, hi, incl)}")
            ok = math.isfinite(value) and (lo <= value if incl else lo < value) and value <= hi
            if not ok:
                raise UserError(f"{name}={value!r} is outside the allowed range {_range_text(lo, hi, incl)}")
        if self.bone not in BONE_PRESETS:
            raise UserError(f"bone={self.bone!r} is not a known preset; allowed: {sorted(BONE_PRESETS)}")
        if not isinstance(self.tracker, bool):
            raise UserError(f"tracker={self.tracker!r} must be True or False")
        entry_mm = self.entry_depth_m * 1e3
        if self.depth_mm < entry_mm + 1.0:
            raise UserError(
                f"depth_mm={self.depth_mm!r} is too shallow: the drill needs {entry_mm:.2f} mm to enter fully at "
                f"beta_deg={self.beta_deg}; allowed: depth_mm >= {entry_mm + 1.0:.2f}"
            )

    @classmethod
    def from_kwargs(cls, **kwargs: Any) -> Scenario:
        """Build from keyword arguments, rejecting unknown names (no silent typos)."""
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(kwargs) - known)
        if unknown:
            raise TypeError(f"unknown scenario argument(s) {unknown}; known: {sorted(known)}")
        return cls(**kwargs)

    def to_dict(self) -> dict[str, Any]:
        """Plain dict (JSON-ready) of the user-facing fields (all scalars: ``dataclasses.asdict`` without its deep copy)."""
        return {f.name: getattr(self, f.name) for f in fields(self)}

    @property
    def beta_rad(self) -> float:
        """Interaction angle β (rad)."""
        return math.radians(self.beta_deg)

    @property
    def feed_m_s(self) -> float:
        """Nominal feed rate (m/s)."""
        return self.feed_mm_s * 1e-3

    @property
    def drill_diameter_m(self) -> float:
        """Drill diameter (m)."""
        return self.drill_diameter_mm * 1e-3

    @property
    def stickout_m(self) -> float:
        """Drill free length (m)."""
        return self.stickout_mm * 1e-3

    @property
    def depth_m(self) -> float:
        """Target tip depth past the planned entry point, along the planned axis (m)."""
        return self.depth_mm * 1e-3

    @property
    def cortical_thickness_m(self) -> float:
        """Cortical layer thickness, normal to the surface (m)."""
        return self.cortical_thickness_mm * 1e-3

    @property
    def tracker_noise_m(self) -> float:
        """Tracker position noise, std per axis (m)."""
        return self.tracker_noise_mm * 1e-3

    @property
    def geometry(self) -> DrillGeometry:
        """Drill point geometry (a standard 118° two-lip twist drill of this diameter)."""
        return DrillGeometry(diameter_m=self.drill_diameter_m)

    @property
    def entry_depth_m(self) -> float:
        """Depth at which the drill is fully engaged, R (cot κ + tan|β|) (m)."""
        return self.geometry.full_engagement_depth_m(self.beta_rad)


def _range_text(lo: float, hi: float, inclusive_low: bool) -> str:
    return f"{'[' if inclusive_low else '('}{lo:g}, {hi:g}]"
