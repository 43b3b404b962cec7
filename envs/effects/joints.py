"""Arm candidate effects: joint friction (the servo lags) and a kinematic calibration error."""

from __future__ import annotations

import dataclasses
from typing import Any, ClassVar

import numba
import numpy as np

from drillgym.envs.constants import CONTROL_DT_S
from drillgym.envs.effects.base import Effect, EffectHost, Param
from drillgym.envs.record_fields import flag_field, float_field
from drillgym.envs.robot import ur5_kernel

SIGN_SMOOTHING_RAD_S = 1e-5
"""Joint speed below which Coulomb friction fades out (rad/s): a joint at rest holds its position."""


def add_geometry_offset(cell: Any, offset_task_m: np.ndarray, marker_base_m: np.ndarray | None = None) -> None:
    """Move the physical tool (and the tracker marker) away from where the controller's model puts it.

    Args:
        cell: the :class:`drillgym.envs.cell.SimCell`.
        offset_task_m: tip offset (m, task frame), added to any offset already set.
        marker_base_m: tracker-marker offset (m, base frame), added likewise; None leaves it.
    """
    off = np.asarray(offset_task_m, dtype=float)
    cell.geometry_offset_task_m = off if cell.geometry_offset_task_m is None else cell.geometry_offset_task_m + off
    # The tool starts where it really is: shift the tip balance's state and the latest sample.
    solver = cell.solver
    solver.rigid = [r + o for r, o in zip(solver.rigid, off.tolist(), strict=True)]
    solver.tip = [r + o for r, o in zip(solver.tip, off.tolist(), strict=True)]
    solver.depth_local = solver.tip[2] + solver.tip[0] * solver.tan_beta
    cell.sample = dataclasses.replace(
        cell.sample, tip=tuple(solver.tip), rigid=tuple(solver.rigid), depth_local=solver.depth_local
    )
    if marker_base_m is not None:
        m = np.asarray(marker_base_m, dtype=float)
        cell.marker_offset_base_m = m if cell.marker_offset_base_m is None else cell.marker_offset_base_m + m


def link_offsets(cell: Any, q_link_rad: np.ndarray, q_motor_rad: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Offsets of the tool tip (task frame, m) and the marker (base frame, m) of links at ``q_link_rad``.

    Against where motors at ``q_motor_rad`` (what the encoders read) would put them.
    """
    tcp, marker = cell._tcp_chain, cell._marker_chain
    tip = cell.R_base_task.T @ (ur5_kernel.frame_pose(q_link_rad, tcp)[1] - ur5_kernel.frame_pose(q_motor_rad, tcp)[1])
    mark = ur5_kernel.frame_pose(q_link_rad, marker)[1] - ur5_kernel.frame_pose(q_motor_rad, marker)[1]
    return tip, mark


def move_links(
    cell: Any, old: tuple[np.ndarray, np.ndarray], new: tuple[np.ndarray, np.ndarray], with_tip: bool = False
) -> None:
    """Replace one effect's share ``old`` of the tool's and the marker's offsets (:func:`link_offsets`) by ``new``.

    The links carry the servo-held point itself, not its target, so the servo has nothing to catch up and the
    encoders see nothing; ``with_tip`` moves the drill tip too (at attach: the tool starts where the links put it).
    """
    (old_tip, old_marker), (tip, marker) = old, new
    geometry = np.zeros(3) if cell.geometry_offset_task_m is None else cell.geometry_offset_task_m
    markers = np.zeros(3) if cell.marker_offset_base_m is None else cell.marker_offset_base_m
    cell.geometry_offset_task_m = geometry - old_tip + tip
    cell.marker_offset_base_m = markers - old_marker + marker
    step = (tip - old_tip).tolist()
    s = cell.solver
    s.rigid = [r + d for r, d in zip(s.rigid, step, strict=True)]
    if with_tip:
        s.tip = [r + d for r, d in zip(s.tip, step, strict=True)]


def commanded_velocity_task_m_s(env: EffectHost) -> np.ndarray:
    """Velocity of the commanded tip target at the start of a step (m/s, task frame).

    The path speed along the planned axis plus the rate of the newest queued correction (taken over one
    agent step).
    """
    rt = env.cell.R_base_task.T
    v = np.array([0.0, 0.0, env.path.speed_m_s(env.feed_scale)])
    if env.pending:
        newest = env.pending[-1][1]
        v += rt @ (newest - env.correction_base_m) / CONTROL_DT_S
    return v


class JointFriction(Effect):
    """Joint friction in a position-controlled arm: each motor lags its target against the friction.

    Per joint the servo's position error is ``δq = −(e_c sgn(q̇) + T_v q̇)`` (Coulomb error e_c in rad,
    viscous lag T_v in s; ``sgn`` fades out below :data:`SIGN_SMOOTHING_RAD_S`), with the joint speeds
    ``q̇ = J⁻¹ v`` of the commanded tip velocity v. The tip (and the whole arm) sits ``J δq`` away from
    the target, so the encoders, the TCP, the tracker and the cutting all see it; the error reverses
    with the motion (feed vs retract). Plausible sizes: friction torques of 5–10 N·m against a servo
    stiffness of 1e4–1e5 N·m/rad give e_c ≈ 1e-4–1e-3 rad; viscous damping of ~10 N·m·s/rad gives
    T_v ≈ 0.1–1 ms (the range allows 20 ms).
    """

    name = "joint_friction"
    summary = "Coulomb + viscous joint friction: the servo lags its target along the motion"
    params = (
        Param("coulomb_rad", 0.0, 1e-3, 0.0, "Coulomb position error per moving joint (rad)"),
        Param("viscous_s", 0.0, 0.02, 0.0, "viscous position error per joint speed (rad per rad/s = s)"),
    )
    channels = frozenset({"force", "torque", "tracker", "q", "tcp"})
    channels_before_contact = frozenset({"tracker", "q", "tcp"})
    compiled = True
    kernel_params = (
        float_field("friction_coulomb_rad", "Joint friction: Coulomb position error per moving joint (rad)."),
        float_field("friction_viscous_s", "Joint friction: viscous position error per joint speed (s)."),
        flag_field("friction_on", "Joint friction is on."),
    )

    def set_kernel_params(self, p: np.void) -> None:
        """The two errors; on, and the servo target shifted, if either is not zero."""
        c, tv = self.values["coulomb_rad"], self.values["viscous_s"]
        p["friction_coulomb_rad"], p["friction_viscous_s"] = c, tv
        if c != 0.0 or tv != 0.0:
            p["friction_on"] = p["target_offset_on"] = True

    def begin_step(self, env: EffectHost) -> None:
        """Set the servo offset from the joint speeds of the commanded motion."""
        cell = env.cell
        v_base = cell.R_base_task @ commanded_velocity_task_m_s(env)
        qd = np.linalg.solve(cell.J_tcp, np.concatenate([v_base, np.zeros(3)]))
        c, tv = self.values["coulomb_rad"], self.values["viscous_s"]
        dq = -(c * np.tanh(qd / SIGN_SMOOTHING_RAD_S) + tv * qd)
        self.servo_offset_task_m = cell.R_base_task.T @ (cell.J_tcp[:3] @ dq)


class KinematicOffset(Effect):
    """Kinematic calibration error: the arm puts the tool a fixed δ away from where its model says.

    The controller computes its joint angles with its nominal kinematics, so the encoders and the RTDE
    TCP are as planned, but the drill tip and the tracker marker (which the tracker sees in the bone's
    frame) are both shifted by δ (base frame): the hole starts off the planned entry point. Typical
    absolute accuracy of an uncalibrated UR5: 0.5–2 mm.
    """

    name = "kinematic_offset"
    summary = "kinematic calibration error: tool and marker shifted by a fixed vector, encoders unaware"
    params: ClassVar[tuple[Param, ...]] = (
        Param("dx_base_m", -2e-3, 2e-3, 0.0, "tool offset along base x (m)"),
        Param("dy_base_m", -2e-3, 2e-3, 0.0, "tool offset along base y (m)"),
        Param("dz_base_m", -2e-3, 2e-3, 0.0, "tool offset along base z (m)"),
    )
    channels = frozenset({"force", "torque", "tracker"})
    channels_before_contact = frozenset({"tracker"})
    compiled = True

    @classmethod
    def initial_guess(cls, evidence: dict[str, Any]) -> dict[str, float] | None:
        """Before contact the tracker sees the offset itself."""
        offset = evidence.get("tracker_offset_task_m")
        if offset is None or not np.all(np.isfinite(offset)):
            return None
        d = np.asarray(evidence["R_base_task"]) @ np.asarray(offset)
        lims = [(p.low, p.high) for p in cls.params]
        return {p.name: float(np.clip(v, lo, hi)) for p, v, (lo, hi) in zip(cls.params, d, lims, strict=True)}

    def attach(self, env: EffectHost) -> None:
        """Shift the physical tool and the marker."""
        d = np.array([self.values["dx_base_m"], self.values["dy_base_m"], self.values["dz_base_m"]])
        if np.any(d != 0.0):
            add_geometry_offset(env.cell, env.cell.R_base_task.T @ d, d)


@numba.njit(cache=True)
def friction_lag(s: Any, p: Any, pend: np.ndarray, speed_m_s: float) -> None:  # pragma: no cover (compiled)
    """:class:`JointFriction`'s ``begin_step`` on an episode's records: the step's servo-target shift (m, task frame).

    The geometry offset plus the friction's lag, from the commanded tip velocity: the path's axial speed
    ``speed_m_s`` and the newest queued correction's change (``pend``: the command queue) over a control step.
    """
    r = p.R_base_task
    v = np.zeros(3)
    v[2] = speed_m_s
    last = s.pending - 1
    d = np.empty(3)
    for i in range(3):
        d[i] = pend[last, 1 + i] - s.correction_base_m[i]
    v += (r.T @ d) / CONTROL_DT_S
    twist = np.zeros(6)
    twist[:3] = r @ v
    jac = s.jacobian
    qd = np.linalg.solve(jac, twist)
    dq = -(p.friction_coulomb_rad * np.tanh(qd / SIGN_SMOOTHING_RAD_S) + p.friction_viscous_s * qd)
    lag = r.T @ (jac[:3] @ dq)
    for i in range(3):
        s.target_offset_task_m[i] = s.geometry_offset_task_m[i] + lag[i] if p.geometry_on else lag[i]
