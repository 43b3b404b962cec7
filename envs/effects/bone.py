"""Bone candidate effects: a density gradient, thermal softening and friction of the entering drill."""

from __future__ import annotations

import math
from typing import Any

import numba
import numpy as np

from drillgym.envs.constants import CONTROL_DT_S
from drillgym.envs.effects.base import Effect, EffectHost, Param
from drillgym.envs.record_fields import float_field

MIN_HARDNESS = 0.05
"""Floor of any hardness factor (the bone never vanishes)."""


class DensityGradient(Effect):
    """Bone density varying linearly with depth: every cutting force scales by ``1 + a + g · d``.

    d is the tip's depth below the local surface (m, along the axis), a the hardness offset at the
    surface (a specimen harder or softer than its preset), g the gradient (per m). Cortical bone's
    mineral density varies by 10–30 % across a cortex a few mm thick.
    """

    name = "density_gradient"
    summary = "bone hardness linear in depth: offset at the surface plus a gradient"
    params = (
        Param("offset", -0.5, 0.5, 0.0, "hardness change at the surface (fraction)"),
        Param("gradient_per_m", -150.0, 150.0, 0.0, "hardness change per metre of depth (1/m; 100 = 10 %/mm)"),
    )
    channels = frozenset({"force", "torque", "tracker"})
    compiled = True

    def attach(self, env: EffectHost) -> None:
        """Multiply the force table by the profile."""
        a, g = self.values["offset"], self.values["gradient_per_m"]
        if a == 0.0 and g == 0.0:
            return
        solver = env.cell.solver
        d = solver.table.depth_m
        profile = np.maximum(1.0 + a + g * np.maximum(d, 0.0), MIN_HARDNESS)
        if solver.depth_profile is not None:
            profile = profile * solver.depth_profile
        solver.set_depth_profile(profile)


class ThermalSoftening(Effect):
    """Thermal softening: the bone softens with the heat the drill has put into it.

    Forces scale by ``1 − a (1 − exp(−W / W₀))``, W the cutting work done so far (J): the spindle's
    ``|M_z| ω`` plus the feed's ``|F_z| v``, summed over the episode. A saturating loss a with a heat scale
    W₀. Drilling heats cortical bone by 10–50 K within seconds (1.5 mm drill: ~1–3 W); its strength
    falls by ~0.5–1 % per K.
    """

    name = "thermal_softening"
    summary = "forces fall with the cutting work done (saturating exponential in the heat put in)"
    params = (
        Param("softening", 0.0, 0.8, 0.0, "asymptotic fractional loss of hardness"),
        Param("work_j", 1.0, 200.0, 20.0, "cutting work for 63 % of the loss (J)"),
    )
    channels = frozenset({"force", "torque", "tracker"})
    compiled = True
    kernel_params = (
        float_field("softening", "Thermal softening: asymptotic fractional loss of hardness (0: off)."),
        float_field("softening_work_j", "Thermal softening: cutting work for 63 % of the loss (J)."),
    )
    kernel_state = (float_field("work_j", "Thermal softening: cutting work done so far (J)."),)

    def attach(self, env: EffectHost) -> None:
        """Cold bone."""
        self.work_j = 0.0

    def set_kernel_params(self, p: np.void) -> None:
        """The loss and its heat scale."""
        p["softening"] = self.values["softening"]
        p["softening_work_j"] = self.values["work_j"]

    def load_kernel_state(self, s: np.void) -> None:
        """The work done so far."""
        s["work_j"] = self.work_j

    def store_kernel_state(self, s: np.void) -> None:
        """The work done so far."""
        self.work_j = float(s["work_j"])

    def begin_step(self, env: EffectHost) -> None:
        """Add the last step's cutting work and scale the specimen's forces by the softening reached."""
        a = self.values["softening"]
        if a == 0.0:
            return
        smp = env.cell.sample
        omega = 2.0 * math.pi * env.scenario.spindle_rpm / 60.0
        power_w = abs(smp.torque_axis) * omega + abs(smp.force[2]) * max(env.path.speed_m_s(env.feed_scale), 0.0)
        self.work_j += power_w * CONTROL_DT_S
        factor = 1.0 - a * (1.0 - math.exp(-self.work_j / self.values["work_j"]))
        env.cell.solver.force_scale = env.cell.specimen_hardness * max(factor, MIN_HARDNESS)


class SkidFriction(Effect):
    """Friction of the entering drill on the inclined surface: it holds the tip against the skid.

    The side guidance of the tip balance (``s²`` of the engaged share s, see ``docs/physics.md`` §4) gains
    ``μ (1 − s)`` while the drill enters: the chisel and the lips rub on the surface before the hole
    exists, so the tip skids less downhill, and the hole (and the deviation locked into it) is smaller.
    """

    name = "skid_friction"
    summary = "friction at entry adds side guidance while the lips are partly engaged"
    params = (Param("mu", 0.0, 3.0, 0.0, "extra side guidance at first touch (share of full guidance)"),)
    channels = frozenset({"force", "torque", "tracker"})
    compiled = True

    def attach(self, env: EffectHost) -> None:
        """Add the entry guidance (:attr:`TipContactSolver.entry_guidance <drillgym.envs.drilling.contact.TipContactSolver.entry_guidance>`)."""
        env.cell.solver.entry_guidance += self.values["mu"]


@numba.njit(cache=True)
def soften(s: Any, p: Any, speed_m_s: float) -> None:  # pragma: no cover (compiled)
    """:class:`ThermalSoftening`'s ``begin_step`` on an episode's records (``speed_m_s``: the path's axial speed).

    The last step's cutting work added (the spindle's ``|M_z| ω`` and the feed's ``|F_z| v`` of the latest sample),
    the force scale it leaves.
    """
    power_w = abs(s.sample[9]) * p.omega_rad_s + abs(s.sample[8]) * max(speed_m_s, 0.0)
    s.work_j += power_w * CONTROL_DT_S
    factor = 1.0 - p.softening * (1.0 - math.exp(-s.work_j / p.softening_work_j))
    s.force_scale_now = p.force_scale * max(factor, MIN_HARDNESS)
