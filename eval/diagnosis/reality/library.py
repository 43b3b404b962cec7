"""The reality generator's effects by name, and the candidate each one corresponds to."""

from __future__ import annotations

from drillgym.eval.diagnosis.reality.arm import ChuckToolLength, JitteredLatency, JointZeroOffsets, StribeckFriction
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
    )
}
"""Every effect ``make-reality`` can switch on."""
