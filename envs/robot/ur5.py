"""UR5 kinematics from the ``example-robot-data`` URDF, through Pinocchio.

Frames: ``base`` is the UR controller's base frame (what RTDE's TCP poses are expressed in); the URDF's
``base_link`` is the same origin turned by π about z. ``tool0`` is the flange. Two frames are added:
``tcp`` at the drill tip (flange + F/T sensor + spindle + stick-out along the flange z axis) and
``tracker_marker`` on the spindle body, where an optical tracker's marker sits.
"""

from __future__ import annotations

import functools
import importlib.metadata
from pathlib import Path

import numpy as np
import pinocchio as pin

TCP_FRAME = "tcp"
TRACKER_FRAME = "tracker_marker"
FLANGE_FRAME = "tool0"

R_BASE_BASELINK = np.diag([-1.0, -1.0, 1.0])
"""Rotation from the URDF ``base_link`` to the UR controller ``base`` frame (π about z)."""

Q_HOME_RAD = np.array([0.0, -1.2, 1.6, -1.97, -1.5708, 0.0])
"""An elbow-up, tool-down seed configuration (rad) for inverse kinematics."""


@functools.cache
def ur5_urdf_path() -> Path:
    """Path of ``ur5_robot.urdf`` inside the installed ``example-robot-data`` package."""
    files = importlib.metadata.files("example-robot-data") or []
    for f in files:
        if str(f).endswith("ur_description/urdf/ur5_robot.urdf"):
            return Path(str(f.locate())).resolve()
    raise FileNotFoundError("example-robot-data is installed without ur_description/urdf/ur5_robot.urdf")


@functools.cache
def _urdf_model() -> pin.Model:
    """The UR5 model parsed from its URDF once per process; each :class:`UR5Kinematics` takes a copy."""
    return pin.buildModelFromUrdf(str(ur5_urdf_path()))


def _se3_to_base(m: pin.SE3) -> np.ndarray:
    """4x4 homogeneous transform of a Pinocchio placement, re-expressed in the UR ``base`` frame."""
    t = np.eye(4)
    t[:3, :3] = R_BASE_BASELINK @ m.rotation
    t[:3, 3] = R_BASE_BASELINK @ m.translation
    return t


class UR5Kinematics:
    """Forward kinematics, Jacobians and inverse kinematics of a UR5 carrying a drill.

    Args:
        tcp_offset_m: distance along the flange z axis from the flange to the drill tip (m).
        tracker_offset_m: marker position in the flange frame (m).
    """

    def __init__(self, tcp_offset_m: float, tracker_offset_m: tuple[float, float, float] = (0.05, 0.0, 0.06)):
        self.model = pin.Model(_urdf_model())  # a copy: frames are added to it below
        flange = self.model.getFrameId(FLANGE_FRAME)
        parent = self.model.frames[flange].parentJoint
        flange_placement = self.model.frames[flange].placement
        for name, offset in ((TCP_FRAME, (0.0, 0.0, tcp_offset_m)), (TRACKER_FRAME, tracker_offset_m)):
            placement = flange_placement * pin.SE3(np.eye(3), np.asarray(offset, dtype=float))
            self.model.addFrame(pin.Frame(name, parent, flange, placement, pin.FrameType.OP_FRAME))
        self.data = self.model.createData()
        self.tcp_offset_m = tcp_offset_m
        self.frame_ids = {n: self.model.getFrameId(n) for n in (FLANGE_FRAME, TCP_FRAME, TRACKER_FRAME)}
        self.q_lower = self.model.lowerPositionLimit.copy()
        self.q_upper = self.model.upperPositionLimit.copy()

    def fk(self, q_rad: np.ndarray, frame: str = TCP_FRAME) -> np.ndarray:
        """Pose ``T_base_frame`` (4x4) of ``frame`` at joint angles ``q_rad``."""
        pin.framesForwardKinematics(self.model, self.data, np.asarray(q_rad, dtype=float))
        return _se3_to_base(self.data.oMf[self.frame_ids[frame]])

    def position(self, q_rad: np.ndarray, frame: str = TCP_FRAME) -> np.ndarray:
        """Position (m, base frame) of ``frame`` at ``q_rad``: ``fk(q_rad, frame)[:3, 3]``, the same numbers, cheaper."""
        pin.framesForwardKinematics(self.model, self.data, np.asarray(q_rad, dtype=float))
        return R_BASE_BASELINK @ self.data.oMf[self.frame_ids[frame]].translation

    def jacobian(self, q_rad: np.ndarray, frame: str = TCP_FRAME) -> np.ndarray:
        """6x6 Jacobian of ``frame`` (linear rows first), at the frame origin, axes of ``base``."""
        q = np.asarray(q_rad, dtype=float)
        j = pin.computeFrameJacobian(
            self.model, self.data, q, self.frame_ids[frame], pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
        )
        out = np.empty((6, 6))
        out[:3] = R_BASE_BASELINK @ j[:3]
        out[3:] = R_BASE_BASELINK @ j[3:]
        return out

    def ik(
        self,
        T_base_target: np.ndarray,
        q_init_rad: np.ndarray | None = None,
        frame: str = TCP_FRAME,
        tol: float = 1e-10,
        max_iter: int = 200,
    ) -> np.ndarray:
        """Joint angles (rad) that put ``frame`` at ``T_base_target`` (damped least squares).

        Raises:
            RuntimeError: no convergence (target out of reach from this seed).
        """
        q = np.array(Q_HOME_RAD if q_init_rad is None else q_init_rad, dtype=float)
        for _ in range(max_iter):
            err = self.pose_error(q, T_base_target, frame)
            if float(err @ err) < tol**2:
                return q
            j = self.jacobian(q, frame)
            q = q + j.T @ np.linalg.solve(j @ j.T + 1e-10 * np.eye(6), err)
        raise RuntimeError(f"IK did not converge for frame {frame!r}: residual {np.linalg.norm(err):.3e}")

    def pose_error(self, q_rad: np.ndarray, T_base_target: np.ndarray, frame: str = TCP_FRAME) -> np.ndarray:
        """Twist (linear m, angular rad; base axes) from the current pose of ``frame`` to the target."""
        t = self.fk(q_rad, frame)
        dp = T_base_target[:3, 3] - t[:3, 3]
        dr = pin.log3(T_base_target[:3, :3] @ t[:3, :3].T)
        return np.concatenate([dp, dr])
