"""Tool candidate effect: the drill sticks out further (or less) than the plan says."""

from __future__ import annotations

import numpy as np

from drillgym.envs.drilling.tool import CantileverTool
from drillgym.envs.effects.base import Effect, EffectHost, Param
from drillgym.envs.effects.joints import add_geometry_offset


class ToolLength(Effect):
    """Tool-length error: the drill's real stick-out is ``l + Δl`` (seated less deep in the chuck).

    Three consequences: the tip is Δl further along the drill axis than the controller's TCP (the hole
    starts earlier), the drill bends more easily (``k_lat = 3EI/(l + Δl)³``) and the F/T sensor sees the
    tip force through a longer arm (``Tx = −(L + Δl) Fy``, ``Ty = (L + Δl) Fx``). The marker is on the
    spindle, so the tracker sees only the arm's response. A chuck tightened on a different length: ±5 mm.
    """

    name = "tool_length"
    summary = "drill stick-out differs from the plan: tip further along the axis, softer drill, longer arm"
    params = (Param("dl_m", -8e-3, 8e-3, 0.0, "real minus planned stick-out (m)"),)
    channels = frozenset({"force", "torque", "tracker"})
    compiled = True

    def attach(self, env: EffectHost) -> None:
        """Rebuild the drill's compliance, move the tip and lengthen the sensor arm."""
        dl = self.values["dl_m"]
        if dl == 0.0:
            return
        cell, sc = env.cell, env.scenario
        tool = CantileverTool(
            diameter_m=sc.drill_diameter_m,
            stickout_m=sc.stickout_m + dl,
            effective_diameter_ratio=cell.params.effective_diameter_ratio,
        )
        cell.set_tool_compliance(tool.compliance_tool_m_n())
        add_geometry_offset(cell, np.array([0.0, 0.0, dl]))
        cell.sensor_arm_m = cell.sensor_arm_m + dl
