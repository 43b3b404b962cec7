"""The UR5: kinematics and Jacobians (Pinocchio), joint compliance, stiffness identification."""

from drillgym.envs.robot.compliance import KTHETA_LI2023_NM_RAD, JointCompliance
from drillgym.envs.robot.ur5 import TCP_FRAME, TRACKER_FRAME, UR5Kinematics, ur5_urdf_path

__all__ = [
    "KTHETA_LI2023_NM_RAD",
    "TCP_FRAME",
    "TRACKER_FRAME",
    "JointCompliance",
    "UR5Kinematics",
    "ur5_urdf_path",
]
