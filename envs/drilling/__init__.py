"""Drilling-force plugin: pure numpy, no PyBullet.

The mechanistic cutting model (Li et al. 2023 §2.1 with edge terms), the bone materials, the drill
geometry, the cantilever tool and the hole left behind. Nothing here imports PyBullet, so the
controllers may reuse it as their own offline model.
"""

from drillgym.envs.drilling.bone import BONE_PRESETS, BoneMaterial, BonePreset, get_bone_preset
from drillgym.envs.drilling.force_model import EngagementTable, ForceModel, engaged_corner_fraction, stage_from_depth
from drillgym.envs.drilling.geometry import DrillGeometry
from drillgym.envs.drilling.hole import Hole
from drillgym.envs.drilling.tool import CantileverTool

__all__ = [
    "BONE_PRESETS",
    "BoneMaterial",
    "BonePreset",
    "CantileverTool",
    "DrillGeometry",
    "EngagementTable",
    "ForceModel",
    "Hole",
    "engaged_corner_fraction",
    "get_bone_preset",
    "stage_from_depth",
]
