"""Plan candidate effect: the bone is not where the registration put it (entry point and surface angle)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from drillgym.envs.effects.base import Effect, EffectHost, Param
from drillgym.envs.effects.joints import add_geometry_offset

REFERENCE_BETA_RAD = math.radians(25.0)
"""The inclination ``surface_dz_m`` is read at: the middle of the surfaces the cell drills (15–35°), so that the
two displacements change the crossings of a set of holes about independently (the fit's search moves one at a
time; along the axis at β = 0, ``dz`` and ``dx`` would trade off along a narrow valley)."""
MIN_TAN_SPREAD = 0.05
"""Spread of ``tan β`` (SD over the episodes) below which the contact shifts cannot tell an entry point along the
slope from one along the axis: :meth:`Registration.initial_guess` then reads the axis offset alone."""


class Registration(Effect):
    """Registration error: the real bone surface lies off the planned one, displaced and tilted.

    The plan puts the entry point at the task origin on a surface inclined by the scenario's β (downhill along
    task +x). Here the real surface is displaced along the planned axis (a point registered short of the
    surface) and by ``dx`` along task x (the registration off along the slope), so it meets the planned axis
    ``dz + dx (tan β − tan β_ref)`` further along it: ``dz`` is the offset of a hole at the reference slope
    β_ref (:data:`REFERENCE_BETA_RAD`), ``dx`` what makes it differ from hole to hole with β. It is inclined by
    ``β + δβ`` (a surface normal read a few degrees off). The drill touches bone that much later, enters on the
    real slope (its lateral push at entry, the depth of full engagement) and the stage bounds move with it; the
    controller, the encoders and the tracker know only the plan. Nothing changes before contact. A surgical
    registration is good to ~0.5–1 mm and a few degrees.
    """

    name = "registration"
    summary = "the bone surface lies off the plan: displaced along the axis and the slope, at another inclination"
    params = (
        Param("surface_dz_m", -2e-3, 2e-3, 0.0, "real surface beyond the plan along the axis, at β_ref (m)"),
        Param("entry_dx_m", -3e-3, 3e-3, 0.0, "real surface displaced downhill along task x (m)"),
        Param("slope_error_rad", -0.15, 0.15, 0.0, "real minus planned surface inclination β (rad)"),
    )
    channels = frozenset({"force", "torque", "tracker"})
    compiled = True

    @classmethod
    def initial_guess(cls, evidence: dict[str, Any]) -> dict[str, float] | None:
        """The displacements that best explain how much later each episode's drill touched (no tilt).

        Each episode's contact shift is ``dz + dx (tan β − tan β_ref)`` (least squares over the episodes); with
        too little spread of β to tell the two apart, ``dz`` alone.
        """
        shift = np.asarray(evidence.get("contact_shift_m", ()), dtype=float)
        if shift.size == 0:
            return None
        tan_beta = np.tan(np.asarray(evidence["beta_rad"], dtype=float)) - math.tan(REFERENCE_BETA_RAD)
        if shift.size >= 3 and float(np.std(tan_beta)) >= MIN_TAN_SPREAD:
            design = np.column_stack([np.ones_like(tan_beta), tan_beta])
            dz, dx = np.linalg.lstsq(design, shift, rcond=None)[0]
        else:
            dz, dx = float(np.mean(shift)), 0.0
        lims = {p.name: (p.low, p.high) for p in cls.params}
        return {
            "surface_dz_m": float(np.clip(dz, *lims["surface_dz_m"])),
            "entry_dx_m": float(np.clip(dx, *lims["entry_dx_m"])),
            "slope_error_rad": 0.0,
        }

    def attach(self, env: EffectHost) -> None:
        """Tilt the surface, then move the tool back from it (the bone, seen from the tool, moves forward)."""
        v = self.values
        if v["slope_error_rad"] != 0.0:
            env.cell.set_surface_angle(env.scenario.beta_rad + v["slope_error_rad"])
        dz = v["surface_dz_m"] + v["entry_dx_m"] * (math.tan(env.scenario.beta_rad) - math.tan(REFERENCE_BETA_RAD))
        if dz != 0.0:
            add_geometry_offset(env.cell, np.array([0.0, 0.0, -dz]))
