"""The surgical plan: what the cell knows before drilling (not privileged simulator state).

A controller is told the plan once per episode: where the hole goes (``T_base_task``), the planned
interaction angle, feed and depth, and the tool as measured on the bench. The simulated and the
real env both expose it as ``env.unwrapped.plan``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from drillgym.envs.scenario import Scenario


@dataclass(frozen=True)
class DrillPlan:
    """Planned hole and tool (SI units, frames named)."""

    T_base_task: np.ndarray = field(repr=False)
    """Task frame in the UR base frame (4x4): origin at the planned entry point, z along the drill."""
    beta_rad: float
    """Planned interaction angle between the drill axis and the surface normal (rad)."""
    feed_m_s: float
    """Nominal feed rate (m/s)."""
    spindle_rpm: float
    """Spindle speed (rpm)."""
    depth_m: float
    """Target depth past the entry point (m)."""
    drill_diameter_m: float
    """Drill diameter (m)."""
    stickout_m: float
    """Drill free length from the chuck, as measured on the bench (m)."""
    tcp_offset_m: float
    """Flange-to-drill-tip distance along the flange z axis (m)."""
    bone: str
    """Specimen preset name the surgeon expects (a controller may use it to pick model coefficients)."""
    cortical_thickness_m: float
    """Expected cortical thickness from imaging (m)."""

    @property
    def R_base_task(self) -> np.ndarray:
        """Task-frame axes in the base frame (3x3)."""
        return self.T_base_task[:3, :3]

    @classmethod
    def from_scenario(cls, scenario: Scenario, T_base_task: np.ndarray, tcp_offset_m: float) -> DrillPlan:
        """The plan a user would write down for this scenario."""
        return cls(
            T_base_task=np.array(T_base_task, dtype=float),
            beta_rad=scenario.beta_rad,
            feed_m_s=scenario.feed_m_s,
            spindle_rpm=scenario.spindle_rpm,
            depth_m=scenario.depth_m,
            drill_diameter_m=scenario.drill_diameter_m,
            stickout_m=scenario.stickout_m,
            tcp_offset_m=tcp_offset_m,
            bone=scenario.bone,
            cortical_thickness_m=scenario.cortical_thickness_m,
        )
