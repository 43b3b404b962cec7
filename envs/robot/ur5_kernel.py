"""Compiled UR5 kinematics for the cell's per-step path (numba): frame pose, Jacobian, an IK step, compliance.

The same chain as :class:`drillgym.envs.robot.ur5.UR5Kinematics` (the URDF through Pinocchio), read once
from its model into arrays: per joint its placement in the parent (rotation, translation) and the local
axis it turns about; per added frame its placement on the last joint. Poses and Jacobians come out in the
UR ``base`` frame as :meth:`UR5Kinematics.fk` and :meth:`UR5Kinematics.jacobian` give them, equal to
within rounding (``tests/envs/test_ur5_kernel.py`` bounds the difference at 1e-12). What the cell runs once
per agent step (:meth:`drillgym.envs.cell.SimCell.end_step`, the tracker's marker) is one call each
instead of a dozen small numpy and Pinocchio calls.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

from drillgym.envs.robot.ur5 import UR5Kinematics

_AXES = {"JointModelRX": 0, "JointModelRY": 1, "JointModelRZ": 2}


@dataclass(frozen=True)
class Chain:
    """A serial chain of axis-aligned revolute joints and one frame on its last link (arrays, SI).

    Attributes:
        rot: (n, 3, 3) each joint's placement rotation in its parent (the first's parent is ``base_link``).
        trans: (n, 3) each joint's placement translation in its parent (m).
        axis: (n,) the local axis each joint turns about (0 x, 1 y, 2 z).
        frame_rot: (3, 3) the frame's rotation on the last joint.
        frame_trans: (3,) the frame's origin on the last joint (m).
    """

    rot: np.ndarray
    trans: np.ndarray
    axis: np.ndarray
    frame_rot: np.ndarray
    frame_trans: np.ndarray

    @classmethod
    def of(cls, kin: UR5Kinematics, frame: str) -> Chain:
        """The chain of ``kin``'s model up to ``frame`` (which must sit on the last joint)."""
        model = kin.model
        n = model.njoints - 1
        rot = np.empty((n, 3, 3))
        trans = np.empty((n, 3))
        axis = np.empty(n, dtype=np.int64)
        for j in range(1, n + 1):
            if model.parents[j] != j - 1:
                raise ValueError(f"joint {model.names[j]!r} is not in a serial chain")
            kind = model.joints[j].shortname()
            if kind not in _AXES:
                raise ValueError(
                    f"joint {model.names[j]!r} is a {kind}; only axis-aligned revolute joints are compiled"
                )
            rot[j - 1] = model.jointPlacements[j].rotation
            trans[j - 1] = model.jointPlacements[j].translation
            axis[j - 1] = _AXES[kind]
        f = model.frames[model.getFrameId(frame)]
        if f.parentJoint != n:
            raise ValueError(f"frame {frame!r} is not on the last joint")
        return cls(rot, trans, axis, np.array(f.placement.rotation), np.array(f.placement.translation))

    def packed(self) -> np.ndarray:
        """The chain as one flat array, the form the kernels take (fewer arguments, cheaper calls).

        ``[n, (rot 9, trans 3, axis 1) per joint, frame_rot 9, frame_trans 3]``.
        """
        n = len(self.axis)
        joints = np.hstack([self.rot.reshape(n, 9), self.trans, self.axis[:, None].astype(float)])
        return np.concatenate([[float(n)], joints.ravel(), self.frame_rot.ravel(), self.frame_trans])


@numba.njit(cache=True)
def _mm(a: np.ndarray, b: np.ndarray) -> np.ndarray:  # pragma: no cover (compiled)
    out = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            out[i, j] = a[i, 0] * b[0, j] + a[i, 1] * b[1, j] + a[i, 2] * b[2, j]
    return out


@numba.njit(cache=True)
def _walk(q: np.ndarray, chain: np.ndarray):  # pragma: no cover (compiled)
    """Frame rotation and origin, joint axes and origins, all in ``base_link`` (``chain``: :meth:`Chain.packed`)."""
    n = int(chain[0])
    r = np.eye(3)
    t = np.empty((3, 3))
    p = np.zeros(3)
    axes = np.empty((n, 3))
    origins = np.empty((n, 3))
    for j in range(n):
        o = 1 + 13 * j
        for i in range(3):  # p += r · trans_j, then r = r · rot_j
            p[i] += r[i, 0] * chain[o + 9] + r[i, 1] * chain[o + 10] + r[i, 2] * chain[o + 11]
        for i in range(3):
            for k in range(3):
                t[i, k] = r[i, 0] * chain[o + k] + r[i, 1] * chain[o + 3 + k] + r[i, 2] * chain[o + 6 + k]
        ax = int(chain[o + 12])
        for i in range(3):
            axes[j, i] = t[i, ax]
            origins[j, i] = p[i]
        # r = t · (rotation of q_j about local axis ax): only the two other columns change
        c, s = math.cos(q[j]), math.sin(q[j])
        u, w = (1, 2) if ax == 0 else ((2, 0) if ax == 1 else (0, 1))
        for i in range(3):
            r[i, ax] = t[i, ax]
            r[i, u] = t[i, u] * c + t[i, w] * s
            r[i, w] = t[i, w] * c - t[i, u] * s
    f = 1 + 13 * n
    rf = np.empty((3, 3))
    pf = p.copy()
    for i in range(3):
        pf[i] += r[i, 0] * chain[f + 9] + r[i, 1] * chain[f + 10] + r[i, 2] * chain[f + 11]
        for k in range(3):
            rf[i, k] = r[i, 0] * chain[f + k] + r[i, 1] * chain[f + 3 + k] + r[i, 2] * chain[f + 6 + k]
    return rf, pf, axes, origins


@numba.njit(cache=True)
def frame_pose(q, chain):  # pragma: no cover
    """``(R, p)`` of the frame in the UR ``base`` frame at joint angles ``q`` (rad): rotation and origin (m)."""
    r, p, _, _ = _walk(q, chain)
    for i in range(2):  # base_link -> base: a half turn about z
        p[i] = -p[i]
        for j in range(3):
            r[i, j] = -r[i, j]
    return r, p


@numba.njit(cache=True)
def frame_jacobian(q, chain):  # pragma: no cover
    """6xn Jacobian at the frame origin, linear rows first, axes of the UR ``base`` frame."""
    _, p, axes, origins = _walk(q, chain)
    n = axes.shape[0]
    jac = np.empty((6, n))
    for j in range(n):
        a = axes[j]
        d = p - origins[j]
        jac[0, j] = -(a[1] * d[2] - a[2] * d[1])
        jac[1, j] = -(a[2] * d[0] - a[0] * d[2])
        jac[2, j] = a[0] * d[1] - a[1] * d[0]
        jac[3, j] = -a[0]
        jac[4, j] = -a[1]
        jac[5, j] = a[2]
    return jac


@numba.njit(cache=True)
def log3(r: np.ndarray) -> np.ndarray:  # pragma: no cover (compiled)
    """Rotation vector (rad) of a rotation matrix: the axis times the angle, as ``pinocchio.log3``."""
    tr = r[0, 0] + r[1, 1] + r[2, 2]
    cos_t = min(max(0.5 * (tr - 1.0), -1.0), 1.0)
    theta = math.acos(cos_t)
    w = np.array([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]])
    if theta < math.pi - 1e-2:
        k = 0.5 * (theta / math.sin(theta) if theta > 1e-4 else 1.0 + theta * theta / 6.0)
        return k * w
    # near a half turn w vanishes: the axis from the symmetric part, R + Rᵀ = 2 cos θ I + 2 (1 - cos θ) a aᵀ,
    # read from its largest diagonal entry, then signed so that w = 2 sin θ a
    d = 1.0 - cos_t
    i = 0
    for k in range(1, 3):
        if r[k, k] > r[i, i]:
            i = k
    out = np.empty(3)
    out[i] = math.sqrt(max((r[i, i] - cos_t) / d, 0.0))
    for k in range(3):
        if k != i:
            out[k] = (r[i, k] + r[k, i]) / (2.0 * d * out[i])
    if out[0] * w[0] + out[1] * w[1] + out[2] * w[2] < 0.0:
        out = -out
    return theta * out


@numba.njit(cache=True)
def solve(a: np.ndarray, b: np.ndarray) -> np.ndarray:  # pragma: no cover (compiled)
    """``a⁻¹ b`` for a small square system (Gaussian elimination, partial pivoting); NaN if ``a`` is singular."""
    n = b.shape[0]
    m = a.copy()
    x = b.copy()
    for c in range(n):
        piv = c
        for r in range(c + 1, n):
            if abs(m[r, c]) > abs(m[piv, c]):
                piv = r
        if m[piv, c] == 0.0:
            x[:] = np.nan
            return x
        if piv != c:
            for k in range(n):
                m[c, k], m[piv, k] = m[piv, k], m[c, k]
            x[c], x[piv] = x[piv], x[c]
        for r in range(c + 1, n):
            f = m[r, c] / m[c, c]
            for k in range(c, n):
                m[r, k] -= f * m[c, k]
            x[r] -= f * x[c]
    for c in range(n - 1, -1, -1):
        s = x[c]
        for k in range(c + 1, n):
            s -= m[c, k] * x[k]
        x[c] = s / m[c, c]
    return x


@numba.njit(cache=True)
def jacobian_and_compliance(q, stiffness, r_task, chain):  # pragma: no cover
    """The Jacobian at ``q`` (6xn, base axes) and ``R_base_taskᵀ (J_v Kθ⁻¹ J_vᵀ) R_base_task`` (3x3, m/N, task axes)."""
    jac = frame_jacobian(q, chain)
    c = np.empty((3, 3))
    for i in range(3):
        for k in range(3):
            s = 0.0
            for j in range(jac.shape[1]):
                s += jac[i, j] * jac[k, j] / stiffness[j]
            c[i, k] = s
    return jac, _mm(_mm(r_task.T, c), r_task)


@numba.njit(cache=True)
def ik_step(q, jac, rigid_task, entry_base, r_task, chain):  # pragma: no cover
    """One Newton step of inverse kinematics from ``q`` (rad), whose Jacobian is ``jac`` (6x6, base axes).

    The target puts the frame at ``entry_base + R_base_task · rigid_task`` (m, base frame) with the
    rotation ``R_base_task``.
    """
    r, p = frame_pose(q, chain)
    err = np.empty(6)
    for i in range(3):
        err[i] = (
            entry_base[i]
            + r_task[i, 0] * rigid_task[0]
            + r_task[i, 1] * rigid_task[1]
            + r_task[i, 2] * rigid_task[2]
            - p[i]
        )
    err[3:] = log3(_mm(r_task, r.T))
    return q + solve(jac, err)


@numba.njit(cache=True)
def joint_deflection(jac, force_task, torque_axis, r_task, stiffness):  # pragma: no cover
    """Joint twist ``δq = Kθ⁻¹ Jᵀ W`` (rad) under a tip load: what the encoders do not see.

    ``W`` is the force ``force_task`` (N) and the torque ``torque_axis`` (N·m) about the drill axis, both
    given in task axes and turned to base axes by ``r_task``; ``jac`` is the TCP Jacobian (6xn, base axes).
    """
    w = np.empty(6)
    for i in range(3):
        w[i] = r_task[i, 0] * force_task[0] + r_task[i, 1] * force_task[1] + r_task[i, 2] * force_task[2]
        w[3 + i] = r_task[i, 2] * torque_axis
    dq = np.empty(jac.shape[1])
    for j in range(jac.shape[1]):
        s = 0.0
        for i in range(6):
            s += jac[i, j] * w[i]
        dq[j] = s / stiffness[j]
    return dq
