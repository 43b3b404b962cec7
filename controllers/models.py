"""The controllers' own models of the cell: the papers' stiffness and force models.

These are the controllers' copies, with their own parameters (what a user would measure or take from
the papers), not a look at the simulator's state: robot compliance from Li's identified joint
stiffness and the robot's nominal kinematics, the drill as a cantilever of the measured stick-out,
and Li's mechanistic force model with coefficients fitted to Li's own published model curve.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from drillgym.envs.drilling.bone import BUFFALO_CORTICAL, BonePreset
from drillgym.envs.drilling.force_model import EngagementTable
from drillgym.envs.drilling.geometry import DrillGeometry
from drillgym.envs.drilling.tool import CantileverTool
from drillgym.envs.plan import DrillPlan
from drillgym.envs.robot.compliance import KTHETA_LI2023_NM_RAD, JointCompliance
from drillgym.envs.robot.ur5 import TCP_FRAME, UR5Kinematics

LI2023_MODEL_PEAK_N = 1.20
"""Peak unbalanced force of the controller's model at β 30°, 0.5 mm/s (N), fitted by least squares to
the lateral F/T force of uncompensated trial holes over the unbalanced stages (``fit_model_peak_n``;
5 seeds of the paper scenario give 1.15-1.27 N, mean 1.20 N). Li fits his model to his uncompensated
experiment the same way (Fig. 9: model and measurement agree in stages 1-2)."""


@functools.lru_cache(maxsize=8)
def _kinematics(tcp_offset_m: float) -> UR5Kinematics:
    return UR5Kinematics(tcp_offset_m)


class RobotComplianceModel:
    """C = J Kθ⁻¹ Jᵀ from the robot's nominal kinematics and a joint-stiffness estimate."""

    def __init__(self, tcp_offset_m: float, stiffness_nm_rad: np.ndarray | None = None) -> None:
        self.kin = _kinematics(round(tcp_offset_m, 9))
        self.joints = JointCompliance(
            np.asarray(KTHETA_LI2023_NM_RAD if stiffness_nm_rad is None else stiffness_nm_rad, dtype=float)
        )

    def jacobian(self, q_rad: np.ndarray) -> np.ndarray:
        """6x6 TCP Jacobian in the base frame."""
        return self.kin.jacobian(np.asarray(q_rad, dtype=float), TCP_FRAME)

    def translational_compliance_m_n(self, q_rad: np.ndarray) -> np.ndarray:
        """C_D (3x3, m/N, base frame) at joint angles ``q_rad``."""
        return self.joints.translational_compliance_m_n(self.jacobian(q_rad))


def tool_compliance_m_n(plan: DrillPlan, effective_diameter_ratio: float = 0.85) -> np.ndarray:
    """K_FD⁻¹: the drill's tip compliance (3x3, m/N, tool frame) for the measured stick-out."""
    tool = CantileverTool(
        diameter_m=plan.drill_diameter_m, stickout_m=plan.stickout_m, effective_diameter_ratio=effective_diameter_ratio
    )
    return tool.compliance_tool_m_n()


@dataclass(frozen=True)
class OfflineForceModel:
    """Li's multi-stage force model, tabulated over the planned depth for one plan.

    The functional form is the mechanistic model of :mod:`drillgym.envs.drilling` (drill geometry, four stages,
    edge + chip terms); its magnitude is one number, the model's peak unbalance at Li's operating
    point (β 30°, 0.5 mm/s, 1.5 mm, 20,000 rpm, tip on the planned axis), fitted to the F/T force of an
    uncompensated trial hole. The trial is drilled with the drill free to skid, so the fit sees less
    force than a drill held on the axis would meet: like Li's, this model underestimates what holding
    the axis takes.
    """

    depth_m: np.ndarray
    lateral_task_n: np.ndarray
    """(n, 2) unbalanced force on the tool, task x and y (N), tip on the planned axis."""

    @classmethod
    def for_plan(cls, plan: DrillPlan, peak_at_li_point_n: float = LI2023_MODEL_PEAK_N) -> OfflineForceModel:
        """Build the tables for ``plan``."""
        bone = _li_model_bone(peak_at_li_point_n)
        geom = DrillGeometry(diameter_m=plan.drill_diameter_m)
        table = _table(geom, bone, plan.beta_rad, plan.cortical_thickness_m, plan.depth_m + 2e-3)
        chip = geom.chip_thickness_m(plan.feed_m_s, plan.spindle_rpm)
        rows = table.edge + chip * table.per_chip
        return cls(depth_m=table.depth_m, lateral_task_n=rows[:, :2].copy())

    def lateral_at(self, depth_m: float | np.ndarray) -> np.ndarray:
        """Predicted unbalanced force (task x, y; N) with the tip at ``depth_m`` on the planned axis.

        One depth gives (2,); N depths (an array) give (N, 2), each row the same numbers as its depth alone.
        """
        cols = [np.interp(depth_m, self.depth_m, self.lateral_task_n[:, i], left=0.0, right=0.0) for i in range(2)]
        return np.array(cols) if np.ndim(depth_m) == 0 else np.stack(cols, axis=-1)

    def lateral_into(self, depth_m: np.ndarray, out: np.ndarray) -> None:
        """:meth:`lateral_at` of N depths written into ``out[:, :2]`` (N, >= 2), the same numbers without a copy."""
        for i in range(2):
            out[:, i] = np.interp(depth_m, self.depth_m, self.lateral_task_n[:, i], left=0.0, right=0.0)


@functools.lru_cache(maxsize=8)
def _li_model_bone(peak_n: float) -> BonePreset:
    """Literature coefficients scaled to Li's model peak (computed once, at Li's operating point)."""
    geom = DrillGeometry()
    base = BonePreset("li2023_model", BUFFALO_CORTICAL, BUFFALO_CORTICAL.scaled(0.15), "Li 2023 model")
    table = _table(geom, base, np.radians(30.0), 8e-3, 4e-3)
    rows = table.edge + geom.chip_thickness_m(0.5e-3, 20000.0) * table.per_chip
    scale = peak_n / float(np.hypot(rows[:, 0], rows[:, 1]).max())
    return base.scaled(scale)


@functools.lru_cache(maxsize=32)
def _table(
    geom: DrillGeometry, bone: BonePreset, beta: float, cortical_m: float, max_depth_m: float
) -> EngagementTable:
    return EngagementTable.build(geom, bone, float(beta), cortical_m, max_depth_m)


def fit_model_peak_n(
    plan: DrillPlan, depth_cmd_m: np.ndarray, lateral_force_n: np.ndarray, entry_depth_m: float
) -> float:
    """Least-squares scale of the force model to a measured uncompensated entry.

    Args:
        plan: the trial hole's plan.
        depth_cmd_m: commanded depth of each F/T sample (m).
        lateral_force_n: filtered lateral F/T force magnitude of each sample (N).
        entry_depth_m: depth at which the drill is fully engaged (m); samples from 0 to it are used.

    Returns:
        The model's peak at Li's operating point (N) that best fits the measurement.
    """
    unit = OfflineForceModel.for_plan(plan, 1.0)
    sel = (depth_cmd_m > 0.0) & (depth_cmd_m < entry_depth_m)
    model = np.array([float(np.hypot(*unit.lateral_at(float(d)))) for d in depth_cmd_m[sel]])
    denom = float(model @ model)
    if denom <= 0.0:
        raise ValueError("no samples in the unbalanced stages to fit the force model to")
    return float(model @ lateral_force_n[sel]) / denom
