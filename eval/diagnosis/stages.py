"""Drilling stage of every sample, estimated from the commanded depth (a real log has no stage).

The commanded tip depth and the planned geometry (β, drill diameter) give Li's stage boundaries
(:func:`drillgym.envs.drilling.force_model.stage_bounds`); the real tip lags and deviates from the command, so
this is the stage the plan expects, which is what a person reading a real log can know.
"""

from __future__ import annotations

import math

import numpy as np

from drillgym.envs.drilling.force_model import stage_bounds
from drillgym.envs.drilling.geometry import DrillGeometry
from drillgym.eval.diagnosis.channels import STAGES


def stage_labels(depth_cmd_m: np.ndarray, phase: np.ndarray, beta_deg: float, drill_diameter_mm: float) -> np.ndarray:
    """Stage index (into :data:`~drillgym.eval.diagnosis.channels.STAGES`) per sample.

    Args:
        depth_cmd_m: commanded tip depth past the planned entry point (m, task z), per sample.
        phase: path phase per sample (0 approach, 1 feed, 2 retract, 3 done).
        beta_deg: planned interaction angle (deg).
        drill_diameter_mm: drill diameter (mm).
    """
    geometry = DrillGeometry(diameter_m=drill_diameter_mm * 1e-3)
    touch, corner_in, half, full = stage_bounds(geometry, math.radians(beta_deg))
    d = np.asarray(depth_cmd_m, dtype=float)
    stage = np.select(
        [d <= touch, d <= corner_in, d < half, d < full],
        [0, 1, 2, 3],
        default=4,
    )
    ph = np.asarray(phase)
    stage = np.where(ph == 0, 0, stage)
    stage = np.where(ph >= 2, STAGES.index("retract"), stage)
    return stage.astype(np.int8)
