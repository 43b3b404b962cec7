"""Plan candidate effect: the bone is not where the registration put it (entry point and surface angle)."""

from __future__ import annotations

import numpy as np

from drillgym.envs.effects.base import Effect, EffectHost, Param
from drillgym.envs.effects.joints import add_geometry_offset


class Registration(Effect):
    """Registration error: the real bone surface lies off the planned one, shifted along the axis and tilted.

    The plan puts the entry point at the task origin on a surface inclined by the scenario's β. Here the real
    surface meets the planned axis ``dz`` further along it (a point registered short of the surface, or a
    registration error along the slope: ``dx`` sideways is ``dx tan β`` along the axis) and is inclined by
    ``β + δβ`` (a surface normal read a few degrees off). The drill touches bone ``dz`` later, enters on the
    real slope (its lateral push at entry, the depth of full engagement) and the stage bounds move with it;
    the controller, the encoders and the tracker know only the plan. Nothing changes before contact.
    A surgical registration is good to ~0.5–1 mm and a few degrees.
    """

    name = "registration"
    summary = "the bone surface lies off the plan: further along the axis and at another inclination"
    params = (
        Param("surface_dz_m", -2e-3, 2e-3, 0.0, "real surface beyond the planned entry point, along the axis (m)"),
        Param("slope_error_rad", -0.15, 0.15, 0.0, "real minus planned surface inclination β (rad)"),
    )
    channels = frozenset({"force", "torque", "tracker"})
    compiled = True

    def attach(self, env: EffectHost) -> None:
        """Tilt the surface, then move the tool back from it (the bone, seen from the tool, moves forward)."""
        dz, dbeta = self.values["surface_dz_m"], self.values["slope_error_rad"]
        if dbeta != 0.0:
            env.cell.set_surface_angle(env.scenario.beta_rad + dbeta)
        if dz != 0.0:
            add_geometry_offset(env.cell, np.array([0.0, 0.0, -dz]))
