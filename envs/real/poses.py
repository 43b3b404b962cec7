"""UR poses: ``[x, y, z, rx, ry, rz]`` (m, rotation vector in rad) <-> 4x4 homogeneous transforms.

UR controllers (and ``ur_rtde``) express a TCP pose as a position and a rotation vector (axis × angle) in
the robot base frame. One tested conversion, used by the real env, the emulator and the benchmarks.
"""

from __future__ import annotations

import math

import numpy as np

from drillgym.envs.errors import UserError


def rotvec_to_matrix(rotvec: np.ndarray) -> np.ndarray:
    """Rotation matrix (3x3) of a rotation vector (rad), Rodrigues' formula."""
    r = np.asarray(rotvec, dtype=float)
    angle = float(np.linalg.norm(r))
    if angle < 1e-12:
        return np.eye(3)
    k = r / angle
    kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + math.sin(angle) * kx + (1.0 - math.cos(angle)) * (kx @ kx)


def matrix_to_rotvec(rot: np.ndarray) -> np.ndarray:
    """Rotation vector (rad, angle in [0, π]) of a rotation matrix (3x3)."""
    r = np.asarray(rot, dtype=float)
    cos_a = min(max((float(np.trace(r)) - 1.0) / 2.0, -1.0), 1.0)
    angle = math.acos(cos_a)
    if angle < 1e-12:
        return np.zeros(3)
    if math.pi - angle > 1e-6:
        axis = np.array([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]]) / (2.0 * math.sin(angle))
        return axis * angle
    # angle ≈ π: R = 2 k kᵀ - I, take the best-conditioned column
    b = (r + np.eye(3)) / 2.0
    i = int(np.argmax(np.diag(b)))
    axis = b[:, i] / math.sqrt(max(b[i, i], 1e-300))
    return axis / np.linalg.norm(axis) * angle


def pose_to_matrix(pose: np.ndarray) -> np.ndarray:
    """4x4 transform of a UR pose ``[x, y, z, rx, ry, rz]`` (m, rad)."""
    p = np.asarray(pose, dtype=float)
    if p.shape != (6,):
        raise UserError(f"a UR pose has 6 values [x, y, z, rx, ry, rz], got shape {p.shape}")
    t = np.eye(4)
    t[:3, :3] = rotvec_to_matrix(p[3:])
    t[:3, 3] = p[:3]
    return t


def matrix_to_pose(transform: np.ndarray) -> np.ndarray:
    """UR pose ``[x, y, z, rx, ry, rz]`` (m, rad) of a 4x4 transform."""
    t = np.asarray(transform, dtype=float)
    return np.concatenate([t[:3, 3], matrix_to_rotvec(t[:3, :3])])


def rotation_angle_rad(rot_a: np.ndarray, rot_b: np.ndarray) -> float:
    """Angle (rad) of the rotation taking ``rot_a`` to ``rot_b``."""
    rel = np.asarray(rot_a, dtype=float).T @ np.asarray(rot_b, dtype=float)
    return math.acos(min(max((float(np.trace(rel)) - 1.0) / 2.0, -1.0), 1.0))
