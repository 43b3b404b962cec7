"""Reality: jittered latency, Stribeck friction, joint zero offsets, a tool in a compliant chuck.

Forms unlike the candidates' fixed delay, Coulomb + viscous friction, constant offset and pure
stick-out error.
"""

from __future__ import annotations

import bisect
import math
from typing import ClassVar

import numpy as np

from drillgym.envs.constants import CONTROL_DT_S
from drillgym.envs.effects.base import EffectHost, Param
from drillgym.envs.robot.ur5 import TCP_FRAME, TRACKER_FRAME
from drillgym.eval.diagnosis.reality.base import RealityEffect, shift_tool


class JitteredLatency(RealityEffect):
    """Jittered latency: each streamed target packet arrives ``mean + jitter · (Exp(1) − 1)`` late (≥ 0).

    The servo never goes back in time (a late packet is held).
    """

    name = "jittered_latency"
    summary = "skewed, jittering delay of the streamed servo target"
    explains = "latency"
    params = (
        Param("mean_s", 0.0, 0.3, 0.0, "mean extra delay (s)"),
        Param("jitter_s", 0.0, 0.1, 0.01, "scale of the exponential jitter (s)"),
    )
    channels = frozenset({"force", "torque", "tracker", "q", "tcp"})

    def attach(self, env: EffectHost) -> None:
        """Empty history."""
        self.times: list[float] = []
        self.targets: list[tuple[float, float, float]] = []
        self.src = -math.inf
        self.delay = self.values["mean_s"]

    def begin_step(self, env: EffectHost) -> None:
        """A new packet: a new delay."""
        v = self.values
        self.delay = max(0.0, v["mean_s"] + v["jitter_s"] * (float(self.rng.exponential()) - 1.0))

    def delay_target(self, t_s: float, target: tuple[float, float, float]) -> tuple[float, float, float]:
        """The target as streamed ``delay`` ago (held if the packet is late)."""
        if self.values["mean_s"] <= 0.0:
            return target
        self.times.append(t_s)
        self.targets.append(target)
        self.src = max(self.src, t_s - self.delay)
        j = bisect.bisect_right(self.times, self.src)
        return self.targets[max(j - 1, 0)]

    def candidate_values(self) -> dict[str, float] | None:
        """``latency``'s delay is the mean one (the jitter's skew aside)."""
        return {"extra_latency_s": self.values["mean_s"]}


class StribeckFriction(RealityEffect):
    """Stribeck joint friction, as a servo position error per joint.

    ``[c + (s − c) exp(−(q̇/v_s)²)] · (2/π) atan(q̇/ε) + T_v q̇`` over the servo stiffness; q̇ is the servo's
    filtered estimate (30 ms) of the commanded joint speed.
    """

    name = "stribeck_friction"
    summary = "Stribeck joint friction (static above Coulomb at low speed) on filtered joint speeds"
    explains = "joint_friction"
    params = (
        Param("static_rad", 0.0, 2e-3, 0.0, "static friction position error (rad)"),
        Param("coulomb_rad", 0.0, 2e-3, 0.0, "sliding friction position error (rad)"),
        Param("stribeck_rad_s", 1e-5, 1e-1, 2e-3, "Stribeck speed (rad/s)"),
        Param("viscous_s", 0.0, 0.2, 0.0, "viscous position error per joint speed (s)"),
    )
    channels = frozenset({"force", "torque", "tracker", "q", "tcp"})

    def attach(self, env: EffectHost) -> None:
        """At rest."""
        self.qd = np.zeros(6)
        self.prev: np.ndarray | None = None

    def begin_step(self, env: EffectHost) -> None:
        """Offset of the servo from the friction at the filtered joint speeds."""
        cell = env.cell
        target = cell.R_base_task.T @ env.correction_base_m + np.array([0.0, 0.0, env.path.s_m])
        v = np.zeros(3) if self.prev is None else (target - self.prev) / CONTROL_DT_S
        self.prev = target
        qd_cmd = np.linalg.solve(cell.J_tcp, np.concatenate([cell.R_base_task @ v, np.zeros(3)]))
        self.qd += (1.0 - math.exp(-CONTROL_DT_S / 0.03)) * (qd_cmd - self.qd)
        p = self.values
        level = p["coulomb_rad"] + (p["static_rad"] - p["coulomb_rad"]) * np.exp(
            -((self.qd / p["stribeck_rad_s"]) ** 2)
        )
        err = level * (2.0 / math.pi) * np.arctan(self.qd / 2e-5) + p["viscous_s"] * self.qd
        self.servo_offset_task_m = cell.R_base_task.T @ (cell.J_tcp[:3] @ -err)

    def candidate_values(self) -> dict[str, float] | None:
        """``joint_friction``'s sliding and viscous terms are the curve's (it has no static peak)."""
        return {"coulomb_rad": self.values["coulomb_rad"], "viscous_s": self.values["viscous_s"]}


class JointZeroOffsets(RealityEffect):
    """Joint zero offsets: the first three joints sit at q + δq while the controller believes q.

    Tip and marker move by their true forward kinematics (not one shared vector).
    """

    name = "joint_offsets"
    summary = "joint zero-position errors of the base, shoulder and elbow"
    explains = "kinematic_offset"
    params: ClassVar[tuple[Param, ...]] = (
        Param("dq0_rad", -5e-3, 5e-3, 0.0, "base joint zero error (rad)"),
        Param("dq1_rad", -5e-3, 5e-3, 0.0, "shoulder joint zero error (rad)"),
        Param("dq2_rad", -5e-3, 5e-3, 0.0, "elbow joint zero error (rad)"),
    )
    channels = frozenset({"force", "torque", "tracker"})

    def _dq(self) -> np.ndarray:
        """The six joints' zero errors (rad)."""
        return np.array([self.values["dq0_rad"], self.values["dq1_rad"], self.values["dq2_rad"], 0.0, 0.0, 0.0])

    def _offsets(self, env: EffectHost) -> tuple[np.ndarray, np.ndarray]:
        cell = env.cell
        dq = self._dq()
        q = cell.q_motor_rad
        tip = cell.kin.fk(q + dq, TCP_FRAME)[:3, 3] - cell.kin.fk(q, TCP_FRAME)[:3, 3]
        marker = cell.kin.fk(q + dq, TRACKER_FRAME)[:3, 3] - cell.kin.fk(q, TRACKER_FRAME)[:3, 3]
        return cell.R_base_task.T @ tip, marker

    def attach(self, env: EffectHost) -> None:
        """Put the tool where the true kinematics have it."""
        tip, marker = self._offsets(env)
        shift_tool(env, self, tip, marker, at_attach=True)

    def begin_step(self, env: EffectHost) -> None:
        """The offsets at the current pose."""
        tip, marker = self._offsets(env)
        shift_tool(env, self, tip, marker, at_attach=False)


class JointZeroDrift(JointZeroOffsets):
    """Joint zero offsets that grow from hole to hole (the arm's gearboxes warming over a session).

    Hole k of a series of n (0-based) has ``δq = δq_first + rate · k`` on the base, shoulder and elbow joints, tip and
    marker moved by the true forward kinematics: a joint-space random-free drift, where the candidate
    ``kinematic_offset_trend`` has a base-frame vector moving linearly with the hole's place in the series.
    """

    name = "joint_drift"
    summary = "joint zero errors growing by a fixed step from hole to hole"
    explains = "kinematic_offset_trend"
    params: ClassVar[tuple[Param, ...]] = (
        Param("dq1_first_rad", -5e-3, 5e-3, 0.0, "shoulder joint zero error at the first hole (rad)"),
        Param("dq0_per_hole_rad", -5e-4, 5e-4, 0.0, "base joint zero error added per hole (rad)"),
        Param("dq1_per_hole_rad", -5e-4, 5e-4, 0.0, "shoulder joint zero error added per hole (rad)"),
        Param("dq2_per_hole_rad", -5e-4, 5e-4, 0.0, "elbow joint zero error added per hole (rad)"),
    )

    def _dq(self) -> np.ndarray:
        """This hole's zero errors (rad)."""
        v, k = self.values, self.series_index
        first = np.array([0.0, v["dq1_first_rad"], 0.0])
        rate = np.array([v["dq0_per_hole_rad"], v["dq1_per_hole_rad"], v["dq2_per_hole_rad"]])
        return np.concatenate([first + k * rate, np.zeros(3)])


class ChuckToolLength(RealityEffect):
    """A drill seated Δl off its planned stick-out, in a chuck that itself tilts under load.

    Tip compliance ``l³/(3EI) + l² c_chuck`` (l = l_plan + Δl), the tip Δl further along the axis and the
    sensor's torque arm Δl longer.
    """

    name = "chuck_tool_length"
    summary = "stick-out error in a compliant chuck"
    explains = "tool_length"
    params = (
        Param("dl_m", -8e-3, 8e-3, 0.0, "real minus planned stick-out (m)"),
        Param("chuck_rad_per_nm", 0.0, 0.2, 0.0, "chuck tilt per N·m of bending moment (rad/(N·m))"),
    )
    channels = frozenset({"force", "torque", "tracker"})

    def attach(self, env: EffectHost) -> None:
        """Soften and lengthen the tool."""
        dl, c_chuck = self.values["dl_m"], self.values["chuck_rad_per_nm"]
        if dl == 0.0 and c_chuck == 0.0:
            return
        cell, sc = env.cell, env.scenario
        length = sc.stickout_m + dl
        d_eff = cell.params.effective_diameter_ratio * sc.drill_diameter_m
        e_pa = 210e9
        inertia = math.pi * d_eff**4 / 64.0
        lateral = length**3 / (3.0 * e_pa * inertia) + length**2 * c_chuck
        axial = length / (e_pa * math.pi * d_eff**2 / 4.0)
        cell.set_tool_compliance(np.diag([lateral, lateral, axial]))
        shift_tool(env, self, np.array([0.0, 0.0, dl]), None, at_attach=True)
        cell.sensor_arm_m = cell.tcp_offset_m + dl

    def candidate_values(self) -> dict[str, float] | None:
        """``tool_length``'s stick-out error is this one (the chuck's tilt aside)."""
        return {"dl_m": self.values["dl_m"]}
