"""Fixed properties of the drilling cell and the calibrated constants of its physics.

Scenario values are what a user varies per experiment; these describe the hardware and the
calibrated model (see ``docs/physics.md`` for how each calibrated value was fit and why it is plausible).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from drillgym.envs.robot.compliance import KTHETA_LI2023_NM_RAD

R_BASE_TASK = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
"""Task-frame axes in the UR base frame: x_task = +y_base (uphill), y_task = +x_base, z_task = -z_base."""


@dataclass(frozen=True)
class CellParams:
    """Hardware layout and calibrated physics constants of the simulated cell."""

    entry_point_base_m: tuple[float, float, float] = (-0.45, -0.11, 0.10)
    """Planned entry point on the bone surface, UR base frame (m)."""
    sensor_to_chuck_m: float = 0.11
    """F/T sensor face to the chuck along the tool axis: sensor, adapter and spindle body (m)."""
    tracker_marker_flange_m: tuple[float, float, float] = (0.05, 0.0, 0.06)
    """Tracker marker position in the flange frame (m): on the spindle body."""
    lateral_cut_resistance_n: float = 100.0
    """K_lat: sideways force per unit of lateral-to-axial cut ratio, i.e. moving the tip sideways by Δp
    while advancing Δz takes K_lat · Δp / Δz (N). Sets how fast a locked-in deviation relaxes:
    over K_lat / k_tool of depth. Calibrated."""
    guidance_exponent: float = 2.0
    """Side guidance grows as (engaged share of the lips)**this: how soon a skidding tip is caught. Calibrated."""
    skid_relief: float = 0.15
    """How much of the surface drop a sideways tip sees: its engagement depth is z + relief · x tan β. Calibrated."""
    wall_guidance_floor: float = 0.03
    """Share of the side guidance the bone gives before the hole has a wall (the full drill diameter just in);
    it grows linearly to 1 over ``wall_length_m`` more of depth. 1: the lips alone guide fully (no wall
    model). Calibrated (``docs/physics.md`` §4, §7)."""
    wall_length_m: float = 1.0e-3
    """Depth of full-diameter hole over which the wall's guidance builds up (m); unused when the floor is 1."""
    effective_diameter_ratio: float = 0.85
    """Drill core bending diameter over nominal diameter (fluted section)."""
    stiffness_nm_rad: np.ndarray = field(default_factory=lambda: KTHETA_LI2023_NM_RAD.copy())
    """UR5 joint stiffness Kθ (N·m/rad), Li 2023 §3.3."""

    @property
    def entry_point(self) -> np.ndarray:
        """Planned entry point (m, base frame) as an array."""
        return np.asarray(self.entry_point_base_m, dtype=float)
