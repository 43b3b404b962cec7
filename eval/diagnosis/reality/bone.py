"""Reality: a harder inner layer, heat-driven softening, load-dependent entry friction, a void.

The void in the bone is deliberately outside the candidate library.
"""

from __future__ import annotations

import math

import numpy as np

from drillgym.envs.constants import CONTROL_DT_S
from drillgym.envs.effects.base import EffectHost, Param
from drillgym.eval.diagnosis.reality.base import RealityEffect


class ForceScaleReset(RealityEffect):
    """Put the specimen's own hardness back at the start of each step; the bone effects then multiply it."""

    name = "_force_scale_reset"

    def begin_step(self, env: EffectHost) -> None:
        """Reset the force scale."""
        env.cell.solver.force_scale = env.cell.specimen_hardness


def _local_depth_m(env: EffectHost) -> float:
    return float(env.cell.sample.depth_local)


class DensityLayer(RealityEffect):
    """A harder (or softer) inner layer: hardness ``1 + a / (1 + exp(−(d − d₀)/w))`` at the tip's local depth d."""

    name = "density_layer"
    summary = "sigmoid hardness change to an inner layer at depth d0"
    explains = "density_gradient"
    params = (
        Param("hardening", -0.6, 1.0, 0.0, "hardness change of the inner layer (fraction)"),
        Param("depth_m", 0.0, 10e-3, 3e-3, "depth of the transition along the axis (m)"),
        Param("width_m", 1e-4, 5e-3, 1e-3, "width of the transition (m)"),
    )
    channels = frozenset({"force", "torque", "tracker"})

    def begin_step(self, env: EffectHost) -> None:
        """Scale the forces by the hardness at the tip."""
        v = self.values
        if v["hardening"] == 0.0:
            return
        x = (_local_depth_m(env) - v["depth_m"]) / v["width_m"]
        env.cell.solver.force_scale *= 1.0 + v["hardening"] / (1.0 + math.exp(-min(max(x, -50.0), 50.0)))


class HeatSoftening(RealityEffect):
    """Heat softening from a lumped heat balance: ``C dT/dt = |M_z| ω + |F_z| v − C T / τ``.

    The bone loses ``k`` of its hardness per kelvin of rise.
    """

    name = "heat_softening"
    summary = "softening proportional to a temperature driven by the cutting power"
    explains = "thermal_softening"
    params = (
        Param("softening_per_k", 0.0, 0.02, 0.0, "hardness lost per kelvin (1/K)"),
        Param("heat_capacity_j_k", 0.01, 2.0, 0.3, "heat capacity of the heated bone (J/K)"),
        Param("cooling_s", 0.5, 120.0, 20.0, "cooling time constant (s): bone conducts heat poorly"),
    )
    channels = frozenset({"force", "torque", "tracker"})

    def attach(self, env: EffectHost) -> None:
        """Bone at body temperature."""
        self.rise_k = 0.0

    def begin_step(self, env: EffectHost) -> None:
        """Integrate the heat balance over the last step and soften."""
        v = self.values
        if v["softening_per_k"] == 0.0:
            return
        smp = env.cell.sample
        omega = 2 * math.pi * env.scenario.spindle_rpm / 60.0
        power_w = abs(smp.torque_axis) * omega + abs(smp.force[2]) * env.path.speed_m_s(env.feed_scale)
        decay = math.exp(-CONTROL_DT_S / v["cooling_s"])
        self.rise_k = self.rise_k * decay + power_w * v["cooling_s"] / v["heat_capacity_j_k"] * (1.0 - decay)
        env.cell.solver.force_scale *= max(1.0 - v["softening_per_k"] * self.rise_k, 0.05)


class EntryFriction(RealityEffect):
    """Entry friction that grows with the load on the surface and fades as the hole forms.

    Side guidance ``+ μ √s (1 − s)²`` (s the engaged share).
    """

    name = "entry_friction"
    summary = "load-dependent friction of the entering drill"
    explains = "skid_friction"
    params = (Param("mu", 0.0, 5.0, 0.0, "friction guidance scale"),)
    channels = frozenset({"force", "torque", "tracker"})

    def attach(self, env: EffectHost) -> None:
        """Install the guidance hook."""
        mu = self.values["mu"]
        if mu == 0.0:
            return
        env.cell.solver.guidance_hook = lambda s, g: g + mu * math.sqrt(max(s, 0.0)) * (1.0 - s) ** 2 if s < 1.0 else g


class BoneVoid(RealityEffect):
    """A void crossing the drill's path (a vascular canal, a resorption cavity).

    Between depths d₀ ± ℓ/2 (smooth 0.1 mm edges) the bone offers only ``residual`` of its hardness.
    Not in the candidate library.
    """

    name = "bone_void"
    summary = "a cavity across the path: the forces collapse over a short depth"
    explains = None
    location = (("fz_n",), ("stable",))
    params = (
        Param("depth_m", 0.0, 10e-3, 2.5e-3, "depth of the void's centre along the axis (m)"),
        Param("length_m", 0.0, 3e-3, 0.0, "length of the void along the axis (m)"),
        Param("residual", 0.0, 1.0, 0.1, "hardness left inside the void (fraction)"),
    )
    channels = frozenset({"force", "torque", "tracker"})

    def begin_step(self, env: EffectHost) -> None:
        """Scale the forces by the bone left at the tip."""
        v = self.values
        if v["length_m"] == 0.0:
            return
        edge = 1e-4
        x = abs(_local_depth_m(env) - v["depth_m"]) - 0.5 * v["length_m"]
        inside = 1.0 / (1.0 + np.exp(min(max(x / (0.25 * edge), -50.0), 50.0)))
        env.cell.solver.force_scale *= 1.0 - (1.0 - v["residual"]) * float(inside)
