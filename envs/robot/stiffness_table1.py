"""Li et al. 2023 Table 1: arm deflections at three poses, measured vs predicted with identified Kθ."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from drillgym.envs.robot.load_tests import (
    LI_TABLE1_LOADS_N,
    LI_TABLE1_POSES_Q_RAD,
    equilibrium_deflection,
    linear_deflection_m,
    point_kinematics,
)
from drillgym.envs.robot.ur5 import UR5Kinematics


@dataclass(frozen=True)
class Table1Comparison:
    """Li et al. 2023 Table 1 reproduction: measured vs predicted deflections at three validation poses."""

    q_rad: np.ndarray
    """(3, 6) validation poses (rad)."""
    force_n: np.ndarray
    """(3, 3) load at each pose (N, base axes)."""
    measured_m: np.ndarray
    """(3, 3) deflection of the simulated true robot, tracker noise included (m, base axes)."""
    predicted_m: np.ndarray
    """(3, 3) ``J Kθ⁻¹ Jᵀ F`` with the identified compliances (m, base axes)."""

    @property
    def error_m(self) -> np.ndarray:
        """Predicted minus measured (m)."""
        return self.predicted_m - self.measured_m

    @property
    def max_abs_error_m(self) -> float:
        """Largest absolute error over poses and axes (m)."""
        return float(np.max(np.abs(self.error_m)))


def reproduce_li_table1(
    kin: UR5Kinematics,
    compliance_rad_nm: np.ndarray,
    true_stiffness_nm_rad: np.ndarray,
    tracker_noise_m: float,
    rng: np.random.Generator,
) -> Table1Comparison:
    """Predict the tip deflection at Li's-style validation poses with the identified compliances.

    The prediction uses the compliance point estimate of every joint, identified or not: joints that are
    not identifiable from tip translations are, by the same token, ones that barely move the tip.
    """
    measured, predicted = [], []
    for q0, force in zip(LI_TABLE1_POSES_Q_RAD, LI_TABLE1_LOADS_N, strict=True):
        _, u = equilibrium_deflection(kin, q0, force, true_stiffness_nm_rad)
        measured.append(u + rng.normal(0.0, tracker_noise_m, 3))
        predicted.append(linear_deflection_m(point_kinematics(kin, q0)[2], force, compliance_rad_nm))
    return Table1Comparison(
        q_rad=LI_TABLE1_POSES_Q_RAD.copy(),
        force_n=LI_TABLE1_LOADS_N.copy(),
        measured_m=np.array(measured),
        predicted_m=np.array(predicted),
    )
