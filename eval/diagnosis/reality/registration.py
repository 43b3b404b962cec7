"""Reality: the bone sits off its registration, displaced along the slope and tilted."""

from __future__ import annotations

import math

import numpy as np

from drillgym.envs.effects.base import EffectHost, Param
from drillgym.envs.effects.registration import REFERENCE_BETA_RAD
from drillgym.eval.diagnosis.reality.base import RealityEffect, shift_tool


class BoneRegistration(RealityEffect):
    """The registered bone is off: displaced by ``(ex, ez)`` in the task frame and tilted by ``δβ``.

    A displacement ``ex`` along the slope moves the surface's crossing with the planned axis by ``ex tan β``, so
    with the scenario's β differing from hole to hole (15–35°) the drill meets bone at a different offset in each
    episode; ``ez`` moves it the same in all. The candidate (``registration``) has both displacements and the
    tilt; here the bone itself is moved (the tool shifted back, as every reality that moves the tool does), there
    the cell's geometry offset.
    """

    name = "bone_registration"
    summary = "bone displaced along the slope and the axis and tilted from its registration"
    explains = "registration"
    params = (
        Param("ex_m", -3e-3, 3e-3, 0.0, "bone displaced downhill along the task x axis (m)"),
        Param("ez_m", -2e-3, 2e-3, 0.0, "bone displaced along the planned axis (m)"),
        Param("tilt_rad", -0.15, 0.15, 0.0, "surface inclination minus the planned β (rad)"),
    )
    channels = frozenset({"force", "torque", "tracker"})

    def attach(self, env: EffectHost) -> None:
        """Tilt the surface and move the tool back by the surface's offset along the axis in this episode."""
        v = self.values
        if v["tilt_rad"] != 0.0:
            env.cell.set_surface_angle(env.scenario.beta_rad + v["tilt_rad"])
        dz = v["ez_m"] + v["ex_m"] * math.tan(env.scenario.beta_rad)
        if dz != 0.0:
            shift_tool(env, self, np.array([0.0, 0.0, -dz]), None, at_attach=True)

    def candidate_values(self) -> dict[str, float] | None:
        """``registration``'s displacements and tilt."""
        v = self.values
        dz = v["ez_m"] + v["ex_m"] * math.tan(REFERENCE_BETA_RAD)  # the candidate's offset is read at β_ref
        return {"surface_dz_m": dz, "entry_dx_m": v["ex_m"], "slope_error_rad": v["tilt_rad"]}
