"""Compiled UR5 kinematics for the cell's per-step path (numba): frame pose, Jacobian, an IK step, compliance.

The same chain as :class:`drillgym.envs.robot.ur5.UR5Kinematics` (the URDF through Pinocchio), read once
from its model into arrays: per joint its placement in the parent (rotation, translation) and the local
axis it turns about; per added frame its placement on the last joint. Poses and Jacobians come out in the
UR ``base`` frame as :meth:`UR5Kinematics.fk` and :meth:`UR5Kinematics.jacobian` give them, equal to
within rounding (``tests/envs/test_ur5_kernel.py`` bounds the difference at 1e-12). What the cell runs once
per agent step (:meth:`drillgym.envs.cell.SimCell.end_step`, the tracker's marker) is one call each
instead of a dozen small numpy and Pinocchio calls.

Inside the compiled step rotations and points travel as tuples (:data:`Rot`, row-major, and :data:`Vec`) and
results go into the caller's arrays (:func:`pose`, :func:`jacobian_into`, :func:`compliance_into`,
:func:`ik_step_into`, :func:`deflected_into`), so a step makes no small arrays; the functions that return arrays
are the same arithmetic, for Python callers and tests.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numba
import numpy as np

from drillgym.envs.robot.ur5 import UR5Kinematics

_AXES = {"JointModelRX": 0, "JointModelRY": 1, "JointModelRZ": 2}

Rot = tuple[float, float, float, float, float, float, float, float, float]
"""A rotation matrix, row-major, as the kernels pass it (no array to allocate)."""
Vec = tuple[float, float, float]
"""A 3-vector as the kernels pass it."""


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
def _times(r: Rot, chain: np.ndarray, o: int) -> Rot:  # pragma: no cover (compiled)
    """``r · m`` with ``m`` the 3x3 stored row-major in ``chain[o : o + 9]``; rotations as row-major 9-tuples."""
    m0, m1, m2, m3, m4, m5, m6, m7, m8 = (
        chain[o], chain[o + 1], chain[o + 2], chain[o + 3], chain[o + 4], chain[o + 5], chain[o + 6], chain[o + 7],
        chain[o + 8],
    )  # fmt: skip
    r00, r01, r02, r10, r11, r12, r20, r21, r22 = r
    return (
        r00 * m0 + r01 * m3 + r02 * m6, r00 * m1 + r01 * m4 + r02 * m7, r00 * m2 + r01 * m5 + r02 * m8,
        r10 * m0 + r11 * m3 + r12 * m6, r10 * m1 + r11 * m4 + r12 * m7, r10 * m2 + r11 * m5 + r12 * m8,
        r20 * m0 + r21 * m3 + r22 * m6, r20 * m1 + r21 * m4 + r22 * m7, r20 * m2 + r21 * m5 + r22 * m8,
    )  # fmt: skip


@numba.njit(cache=True)
def _moved(r: Rot, p: Vec, chain: np.ndarray, o: int) -> Vec:  # pragma: no cover (compiled)
    """``p + r · d`` with ``d`` stored in ``chain[o : o + 3]``."""
    a, b, c = chain[o], chain[o + 1], chain[o + 2]
    return (
        p[0] + (r[0] * a + r[1] * b + r[2] * c),
        p[1] + (r[3] * a + r[4] * b + r[5] * c),
        p[2] + (r[6] * a + r[7] * b + r[8] * c),
    )


@numba.njit(cache=True)
def _turned(t: Rot, ax: int, c: float, s: float) -> Rot:  # pragma: no cover (compiled)
    """``t · (rotation by the angle of cosine c, sine s about local axis ax)``: only the two other columns change."""
    t00, t01, t02, t10, t11, t12, t20, t21, t22 = t
    if ax == 0:
        return (
            t00, t01 * c + t02 * s, t02 * c - t01 * s,
            t10, t11 * c + t12 * s, t12 * c - t11 * s,
            t20, t21 * c + t22 * s, t22 * c - t21 * s,
        )  # fmt: skip
    if ax == 1:
        return (
            t00 * c - t02 * s, t01, t02 * c + t00 * s,
            t10 * c - t12 * s, t11, t12 * c + t10 * s,
            t20 * c - t22 * s, t21, t22 * c + t20 * s,
        )  # fmt: skip
    return (
        t00 * c + t01 * s, t01 * c - t00 * s, t02,
        t10 * c + t11 * s, t11 * c - t10 * s, t12,
        t20 * c + t21 * s, t21 * c - t20 * s, t22,
    )  # fmt: skip


@numba.njit(cache=True)
def _walk(q: np.ndarray, chain: np.ndarray, axes: Any, origins: Any) -> tuple[Rot, Vec]:  # pragma: no cover (compiled)
    """The frame's rotation and origin in ``base_link`` (``chain``: :meth:`Chain.packed`).

    Unless ``axes`` is None (then ``origins`` too), each joint's axis and origin (``base_link``) go to rows of
    ``axes`` and ``origins`` (n, 3).
    """
    n = int(chain[0])
    r: Rot = (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0)
    p: Vec = (0.0, 0.0, 0.0)
    for j in range(n):
        o = 1 + 13 * j
        p = _moved(r, p, chain, o + 9)  # p += r · trans_j, then t = r · rot_j
        t = _times(r, chain, o)
        ax = int(chain[o + 12])
        if axes is not None:
            axes[j, 0], axes[j, 1], axes[j, 2] = t[ax], t[3 + ax], t[6 + ax]
            origins[j, 0], origins[j, 1], origins[j, 2] = p
        r = _turned(t, ax, math.cos(q[j]), math.sin(q[j]))
    f = 1 + 13 * n
    return _times(r, chain, f), _moved(r, p, chain, f + 9)


@numba.njit(cache=True)
def _in_base(r: Rot, p: Vec) -> tuple[Rot, Vec]:  # pragma: no cover (compiled)
    """A pose in ``base_link`` turned into the UR ``base`` frame: a half turn about z."""
    return (-r[0], -r[1], -r[2], -r[3], -r[4], -r[5], r[6], r[7], r[8]), (-p[0], -p[1], p[2])


@numba.njit(cache=True)
def pose(q: np.ndarray, chain: np.ndarray) -> tuple[Rot, Vec]:  # pragma: no cover (compiled)
    """:func:`frame_pose` as tuples (the rotation row-major), without making arrays: what the kernels call."""
    r, p = _walk(q, chain, None, None)
    return _in_base(r, p)


@numba.njit(cache=True)
def frame_pose(q, chain):  # pragma: no cover
    """``(R, p)`` of the frame in the UR ``base`` frame at joint angles ``q`` (rad): rotation and origin (m)."""
    r, p = pose(q, chain)
    return np.array(r).reshape(3, 3), np.array(p)


@numba.njit(cache=True)
def jacobian_into(
    q: np.ndarray, chain: np.ndarray, jac: np.ndarray, axes: np.ndarray, origins: np.ndarray
) -> tuple[Rot, Vec]:  # pragma: no cover
    """:func:`frame_jacobian` into ``jac`` (6xn), with ``axes`` and ``origins`` (n, 3) as scratch.

    Returns the frame's pose at ``q`` as :func:`pose` gives it, which the walk computes anyway.
    """
    r, p = _walk(q, chain, axes, origins)
    for j in range(axes.shape[0]):
        a0, a1, a2 = axes[j, 0], axes[j, 1], axes[j, 2]
        d0, d1, d2 = p[0] - origins[j, 0], p[1] - origins[j, 1], p[2] - origins[j, 2]
        jac[0, j] = -(a1 * d2 - a2 * d1)
        jac[1, j] = -(a2 * d0 - a0 * d2)
        jac[2, j] = a0 * d1 - a1 * d0
        jac[3, j] = -a0
        jac[4, j] = -a1
        jac[5, j] = a2
    return _in_base(r, p)


@numba.njit(cache=True)
def frame_jacobian(q, chain):  # pragma: no cover
    """6xn Jacobian at the frame origin, linear rows first, axes of the UR ``base`` frame."""
    n = int(chain[0])
    jac = np.empty((6, n))
    jacobian_into(q, chain, jac, np.empty((n, 3)), np.empty((n, 3)))
    return jac


@numba.njit(cache=True)
def _rotvec(r: Rot) -> Vec:  # pragma: no cover (compiled)
    """:func:`log3` of a rotation given row-major as a 9-tuple."""
    tr = r[0] + r[4] + r[8]
    cos_t = min(max(0.5 * (tr - 1.0), -1.0), 1.0)
    theta = math.acos(cos_t)
    w0, w1, w2 = r[7] - r[5], r[2] - r[6], r[3] - r[1]
    if theta < math.pi - 1e-2:
        k = 0.5 * (theta / math.sin(theta) if theta > 1e-4 else 1.0 + theta * theta / 6.0)
        return k * w0, k * w1, k * w2
    # near a half turn w vanishes: the axis from the symmetric part, R + Rᵀ = 2 cos θ I + 2 (1 - cos θ) a aᵀ,
    # read from its largest diagonal entry, then signed so that w = 2 sin θ a
    d = 1.0 - cos_t
    i = 0
    for k in range(1, 3):
        if r[4 * k] > r[4 * i]:
            i = k
    a_i = math.sqrt(max((r[4 * i] - cos_t) / d, 0.0))
    a = [0.0, 0.0, 0.0]
    for k in range(3):
        a[k] = a_i if k == i else (r[3 * i + k] + r[3 * k + i]) / (2.0 * d * a_i)
    if a[0] * w0 + a[1] * w1 + a[2] * w2 < 0.0:
        return theta * -a[0], theta * -a[1], theta * -a[2]
    return theta * a[0], theta * a[1], theta * a[2]


@numba.njit(cache=True)
def log3(r: np.ndarray) -> np.ndarray:  # pragma: no cover (compiled)
    """Rotation vector (rad) of a rotation matrix: the axis times the angle, as ``pinocchio.log3``."""
    return np.array(_rotvec((r[0, 0], r[0, 1], r[0, 2], r[1, 0], r[1, 1], r[1, 2], r[2, 0], r[2, 1], r[2, 2])))


@numba.njit(cache=True)
def solve_in_place(m: np.ndarray, x: np.ndarray) -> None:  # pragma: no cover (compiled)
    """``x <- m⁻¹ x`` for a small square system (Gaussian elimination, partial pivoting; ``m`` is overwritten).

    ``x`` is all NaN if ``m`` is singular.
    """
    n = x.shape[0]
    for c in range(n):
        piv = c
        for r in range(c + 1, n):
            if abs(m[r, c]) > abs(m[piv, c]):
                piv = r
        if m[piv, c] == 0.0:
            x[:] = np.nan
            return
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


@numba.njit(cache=True)
def solve(a: np.ndarray, b: np.ndarray) -> np.ndarray:  # pragma: no cover (compiled)
    """``a⁻¹ b`` for a small square system (Gaussian elimination, partial pivoting); NaN if ``a`` is singular."""
    x = b.copy()
    solve_in_place(a.copy(), x)
    return x


@numba.njit(cache=True)
def _weighted(jac: np.ndarray, i: int, k: int, stiffness: np.ndarray) -> float:  # pragma: no cover (compiled)
    """``Σ_j J[i, j] J[k, j] / Kθ[j]``, summed in joint order."""
    s = 0.0
    for j in range(jac.shape[1]):
        s += jac[i, j] * jac[k, j] / stiffness[j]
    return s


@numba.njit(cache=True)
def compliance_into(
    jac: np.ndarray, stiffness: np.ndarray, r_task: np.ndarray, out: np.ndarray
) -> None:  # pragma: no cover
    """``R_base_taskᵀ (J_v Kθ⁻¹ J_vᵀ) R_base_task`` (3x3, m/N, task axes) into ``out``."""
    c = (
        _weighted(jac, 0, 0, stiffness), _weighted(jac, 0, 1, stiffness), _weighted(jac, 0, 2, stiffness),
        _weighted(jac, 1, 0, stiffness), _weighted(jac, 1, 1, stiffness), _weighted(jac, 1, 2, stiffness),
        _weighted(jac, 2, 0, stiffness), _weighted(jac, 2, 1, stiffness), _weighted(jac, 2, 2, stiffness),
    )  # fmt: skip
    for i in range(3):  # a = Rᵀ c (row i), then out = a R
        a0 = r_task[0, i] * c[0] + r_task[1, i] * c[3] + r_task[2, i] * c[6]
        a1 = r_task[0, i] * c[1] + r_task[1, i] * c[4] + r_task[2, i] * c[7]
        a2 = r_task[0, i] * c[2] + r_task[1, i] * c[5] + r_task[2, i] * c[8]
        for j in range(3):
            out[i, j] = a0 * r_task[0, j] + a1 * r_task[1, j] + a2 * r_task[2, j]


@numba.njit(cache=True)
def jacobian_and_compliance(q, stiffness, r_task, chain):  # pragma: no cover
    """The Jacobian at ``q`` (6xn, base axes) and ``R_base_taskᵀ (J_v Kθ⁻¹ J_vᵀ) R_base_task`` (3x3, m/N, task axes)."""
    jac = frame_jacobian(q, chain)
    c = np.empty((3, 3))
    compliance_into(jac, stiffness, r_task, c)
    return jac, c


@numba.njit(cache=True)
def ik_step_into(q, pose_q, jac, rigid_task, entry_base, r_task, m, x, q_out):  # pragma: no cover
    """:func:`ik_step` into ``q_out`` (n,), with ``m`` (n, n) and ``x`` (n,) as scratch.

    ``pose_q``: the frame's pose at ``q`` as :func:`pose` gives it; ``rigid_task`` a 3-tuple.
    """
    r, p = pose_q
    for i in range(3):
        x[i] = (
            entry_base[i]
            + r_task[i, 0] * rigid_task[0]
            + r_task[i, 1] * rigid_task[1]
            + r_task[i, 2] * rigid_task[2]
            - p[i]
        )
    e = (  # R_base_task · Rᵀ
        r_task[0, 0] * r[0] + r_task[0, 1] * r[1] + r_task[0, 2] * r[2],
        r_task[0, 0] * r[3] + r_task[0, 1] * r[4] + r_task[0, 2] * r[5],
        r_task[0, 0] * r[6] + r_task[0, 1] * r[7] + r_task[0, 2] * r[8],
        r_task[1, 0] * r[0] + r_task[1, 1] * r[1] + r_task[1, 2] * r[2],
        r_task[1, 0] * r[3] + r_task[1, 1] * r[4] + r_task[1, 2] * r[5],
        r_task[1, 0] * r[6] + r_task[1, 1] * r[7] + r_task[1, 2] * r[8],
        r_task[2, 0] * r[0] + r_task[2, 1] * r[1] + r_task[2, 2] * r[2],
        r_task[2, 0] * r[3] + r_task[2, 1] * r[4] + r_task[2, 2] * r[5],
        r_task[2, 0] * r[6] + r_task[2, 1] * r[7] + r_task[2, 2] * r[8],
    )
    x[3], x[4], x[5] = _rotvec(e)
    m[:, :] = jac
    solve_in_place(m, x)
    for j in range(q.shape[0]):
        q_out[j] = q[j] + x[j]


@numba.njit(cache=True)
def ik_step(q, jac, rigid_task, entry_base, r_task, chain):  # pragma: no cover
    """One Newton step of inverse kinematics from ``q`` (rad), whose Jacobian is ``jac`` (6x6, base axes).

    The target puts the frame at ``entry_base + R_base_task · rigid_task`` (m, base frame) with the
    rotation ``R_base_task``.
    """
    n = q.shape[0]
    out = np.empty(n)
    rigid = (rigid_task[0], rigid_task[1], rigid_task[2])
    ik_step_into(q, pose(q, chain), jac, rigid, entry_base, r_task, np.empty((n, n)), np.empty(n), out)
    return out


@numba.njit(cache=True)
def _twist(
    jac: np.ndarray, force_task: Vec, torque_axis: float, r_task: np.ndarray, stiffness: np.ndarray, j: int
) -> float:  # pragma: no cover
    """Joint ``j``'s ``(Jᵀ W)_j / Kθ_j`` (rad) for :func:`joint_deflection`'s wrench ``W``."""
    f0, f1, f2 = force_task
    w = (
        r_task[0, 0] * f0 + r_task[0, 1] * f1 + r_task[0, 2] * f2,
        r_task[1, 0] * f0 + r_task[1, 1] * f1 + r_task[1, 2] * f2,
        r_task[2, 0] * f0 + r_task[2, 1] * f1 + r_task[2, 2] * f2,
        r_task[0, 2] * torque_axis,
        r_task[1, 2] * torque_axis,
        r_task[2, 2] * torque_axis,
    )
    s = 0.0
    for i in range(6):
        s += jac[i, j] * w[i]
    return s / stiffness[j]


@numba.njit(cache=True)
def deflected_into(q, jac, force_task, torque_axis, r_task, stiffness, out):  # pragma: no cover
    """``q + δq`` (rad) into ``out``, ``δq`` :func:`joint_deflection`'s (``force_task`` a 3-tuple)."""
    for j in range(jac.shape[1]):
        out[j] = q[j] + _twist(jac, force_task, torque_axis, r_task, stiffness, j)


@numba.njit(cache=True)
def joint_deflection(jac, force_task, torque_axis, r_task, stiffness):  # pragma: no cover
    """Joint twist ``δq = Kθ⁻¹ Jᵀ W`` (rad) under a tip load: what the encoders do not see.

    ``W`` is the force ``force_task`` (N) and the torque ``torque_axis`` (N·m) about the drill axis, both
    given in task axes and turned to base axes by ``r_task``; ``jac`` is the TCP Jacobian (6xn, base axes).
    """
    dq = np.empty(jac.shape[1])
    force = (force_task[0], force_task[1], force_task[2])
    for j in range(jac.shape[1]):
        dq[j] = _twist(jac, force, torque_axis, r_task, stiffness, j)
    return dq
