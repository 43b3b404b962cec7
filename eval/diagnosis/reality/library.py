"""The reality generator's effects by name, and the candidate each one corresponds to."""

from __future__ import annotations

from drillgym.eval.diagnosis.reality.arm import (
    ChuckToolLength,
    JitteredLatency,
    JointZeroDrift,
    JointZeroOffsets,
    StribeckFriction,
)
from drillgym.eval.diagnosis.reality.backlash import GearBacklash
from drillgym.eval.diagnosis.reality.base import RealityEffect
from drillgym.eval.diagnosis.reality.bone import BoneVoid, DensityLayer, EntryFriction, HeatSoftening
from drillgym.eval.diagnosis.reality.registration import BoneRegistration
from drillgym.eval.diagnosis.reality.resonance import MountResonance
from drillgym.eval.diagnosis.reality.sensor import (
    FTEpisodeWarmup,
    FTLateralGain,
    FTLoadBias,
    FTWarmup,
    TrackerSmoothing,
    WobblyRunout,
)
from drillgym.eval.diagnosis.reality.sensor_faults import FTBroadbandNoise, FTTorqueGain
from drillgym.eval.diagnosis.reality.spindle import SpindleMotor

REALITY_EFFECTS: dict[str, type[RealityEffect]] = {
    cls.name: cls
    for cls in (
        FTWarmup,
        FTEpisodeWarmup,
        JitteredLatency,
        StribeckFriction,
        JointZeroOffsets,
        GearBacklash,
        ChuckToolLength,
        DensityLayer,
        HeatSoftening,
        EntryFriction,
        SpindleMotor,
        WobblyRunout,
        MountResonance,
        FTLateralGain,
        FTLoadBias,
        TrackerSmoothing,
        BoneRegistration,
        BoneVoid,
        FTBroadbandNoise,
        FTTorqueGain,
        JointZeroDrift,
    )
}
"""Every effect ``make-reality`` can switch on."""

EXAMPLES: dict[str, str] = {
    "ft_warmup": "ft_warmup:fz_n=2.5,fx_n=1.2",
    "episode_warmup": "episode_warmup:spread_n=2.5",
    "jittered_latency": "jittered_latency:mean_s=0.03,jitter_s=0.01",
    "stribeck_friction": "stribeck_friction:static_rad=2e-4,coulomb_rad=1.5e-4",
    "joint_offsets": "joint_offsets:dq1_rad=5e-4",
    "gear_backlash": "gear_backlash:play0_rad=2e-4,play1_rad=2e-4,play2_rad=2e-4",
    "chuck_tool_length": "chuck_tool_length:dl_m=0.002,chuck_rad_per_nm=0.02",
    "density_layer": "density_layer:hardening=0.2",
    "heat_softening": "heat_softening:softening_per_k=0.002",
    "entry_friction": "entry_friction:mu=0.2",
    "spindle_motor": "spindle_motor:sag_per_nm=100",
    "wobbly_runout": "wobbly_runout:runout_m=2e-5",
    "mount_resonance": "mount_resonance:freq_xy_hz=25,freq_z_hz=25,damping=0.08",
    "ft_lateral_gain": "ft_lateral_gain:gain=0.15,crosstalk=0.005",
    "ft_load_bias": "ft_load_bias:bx_n=0.6,bz_n=-0.8",
    "tracker_smoothing": "tracker_smoothing:tau_s=0.06",
    "bone_registration": "bone_registration:ex_m=1e-3",
    "bone_void": "bone_void:length_m=0.001",
    "ft_broadband_noise": "ft_broadband_noise:sigma_n=0.06",
    "ft_torque_gain": "ft_torque_gain:gain=0.2",
    "joint_drift": "joint_drift:dq1_per_hole_rad=1e-4",
}
"""A plausible spec of each reality effect: the withheld-effect benchmark's moderate case
(:mod:`drillgym.eval.diagnosis.bench.cases`; a test keeps them equal)."""


def switches(cls: type[RealityEffect]) -> tuple[str, ...]:
    """The parameters that switch ``cls`` on: those whose default is 0 (the others shape it: a time constant, a depth).

    With every switch at 0 the effect changes nothing, whatever its shape parameters (``bone_void`` with
    ``length_m=0`` has no void, ``mount_resonance`` with ``damping=0`` no mount).
    """
    own = tuple(p.name for p in cls.params if p.default == 0.0)
    return own or tuple(p.name for p in cls.params)


def switched_on(effect: RealityEffect) -> bool:
    """Whether ``effect``'s values switch anything on (a switch away from 0, :func:`switches`)."""
    defaults = {p.name: p.default for p in effect.params}
    return any(effect.values[name] != defaults[name] for name in switches(type(effect)))


def describe_parameters(name: str) -> str:
    """One line: ``name``'s parameters, each with its range and default, and an example spec."""
    cls = REALITY_EFFECTS[name]
    params = "; ".join(
        f"{p.name} in [{p.low:g}, {p.high:g}] (default {p.default:g}): {p.description}" for p in cls.params
    )
    return f"parameters: {params}; e.g. {EXAMPLES[name]}"


def parameters_help() -> str:
    """Every reality effect's parameters as plain text (``drillgym make-reality --help``)."""
    lines = ["reality effects and their parameters (range, default; * switches the effect on, off at 0):"]
    for name, cls in REALITY_EFFECTS.items():
        lines.append(f"  {name}: {cls.summary}")
        on = switches(cls)
        for p in cls.params:
            mark = "*" if p.name in on else " "
            lines.append(f"    {mark} {p.name} [{p.low:g}, {p.high:g}], default {p.default:g}: {p.description}")
        lines.append(f"      e.g. --effects {EXAMPLES[name]}")
    return "\n".join(lines)


def parameters_table() -> str:
    """Every reality effect's parameters as a Markdown table (``docs/diagnosis.md`` holds it; a test compares)."""
    rows = ["| Reality effect | Parameter | Range | Default | Meaning |", "|---|---|---|---|---|"]
    for name, cls in REALITY_EFFECTS.items():
        on = switches(cls)
        for i, p in enumerate(cls.params):
            label = f"`{name}` (e.g. `{EXAMPLES[name]}`)" if i == 0 else ""
            param = f"**`{p.name}`**" if p.name in on else f"`{p.name}`"
            rows.append(f"| {label} | {param} | [{p.low:g}, {p.high:g}] | {p.default:g} | {p.description} |")
    return "\n".join(rows)
