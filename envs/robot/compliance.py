"""Quasi-static joint compliance (Li et al. 2023 §2.2.1, Zhang et al. 2005 §II).

Links are rigid, joints are torsion springs: a wrench ``W`` at a frame turns the joints by
``δq = Kθ⁻¹ Jᵀ W`` and moves the frame by ``δx = J Kθ⁻¹ Jᵀ W``. Springs this stiff
(1.6–7.2e4 N·m/rad) are unstable as explicit PyBullet joint springs above ~0.1 ms steps; the papers'
model is quasi-static, and so is ours: the arm is always at its static equilibrium under the load.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

KTHETA_LI2023_NM_RAD = np.array([2.53e4, 2.18e4, 1.62e4, 7.23e4, 6.62e4, 4.43e4])
"""UR5 joint stiffnesses identified by Li et al. 2023 §3.3 (N·m/rad), shoulder pan to wrist 3."""


@dataclass(frozen=True)
class JointCompliance:
    """Joint torsional stiffness of a 6-axis arm."""

    stiffness_nm_rad: np.ndarray = field(default_factory=lambda: KTHETA_LI2023_NM_RAD.copy())
    """Kθ, one value per joint (N·m/rad)."""

    def joint_deflection_rad(self, jacobian: np.ndarray, wrench: np.ndarray) -> np.ndarray:
        """δq = Kθ⁻¹ Jᵀ W for a wrench W = (force N, torque N·m) in the Jacobian's axes."""
        return (jacobian.T @ np.asarray(wrench, dtype=float)) / self.stiffness_nm_rad

    def cartesian_compliance(self, jacobian: np.ndarray) -> np.ndarray:
        """C = J Kθ⁻¹ Jᵀ (6x6; m/N, rad/N·m blocks)."""
        return (jacobian / self.stiffness_nm_rad) @ jacobian.T

    def translational_compliance_m_n(self, jacobian: np.ndarray) -> np.ndarray:
        """The force-to-translation block C_D (3x3, m/N): the frame's drift under a pure force."""
        jv = jacobian[:3]
        return (jv / self.stiffness_nm_rad) @ jv.T
