"""Candidate unmodelled effects: small, documented extensions of the simulated cell.

Each effect has physical parameters with ranges and a default that switches it off, and acts through
the env's hooks (:mod:`drillgym.envs.effects.base`); the sim-to-real diagnosis (``eval/diagnosis``) fits them to
logs. Switch effects on with ``env.unwrapped.set_effects([...])`` or ``reset(options={"effects": [...]})``::

    from drillgym.envs.effects import build_effects
    env.unwrapped.set_effects(build_effects("tool_length:dl_m=0.003+ft_drift:fz_rate_n_s=0.02"))

``docs/diagnosis.md`` lists every effect, its parameters and the channels it changes.
"""

from drillgym.envs.effects.base import CHANNEL_GROUPS, Effect, EffectStack, Param, TraceView
from drillgym.envs.effects.bone import DensityGradient, SkidFriction, ThermalSoftening
from drillgym.envs.effects.joints import JointFriction, KinematicOffset, add_geometry_offset
from drillgym.envs.effects.registration import Registration
from drillgym.envs.effects.registry import EFFECTS, build_effects, parse_effect_spec
from drillgym.envs.effects.sensor import FTDrift, ToolRunout
from drillgym.envs.effects.servo import ServoDeadband
from drillgym.envs.effects.spindle import SpindleSag
from drillgym.envs.effects.timing import DelayLine, Latency
from drillgym.envs.effects.tool import ToolLength
from drillgym.envs.effects.tracker import TrackerLatency

__all__ = [
    "CHANNEL_GROUPS",
    "EFFECTS",
    "DelayLine",
    "DensityGradient",
    "Effect",
    "EffectStack",
    "FTDrift",
    "JointFriction",
    "KinematicOffset",
    "Latency",
    "Param",
    "Registration",
    "ServoDeadband",
    "SkidFriction",
    "SpindleSag",
    "ThermalSoftening",
    "ToolLength",
    "ToolRunout",
    "TraceView",
    "TrackerLatency",
    "add_geometry_offset",
    "build_effects",
    "parse_effect_spec",
]
