"""Sensor-side candidate effects: they change what the F/T sensor reads, not the physics.

They act on the true wrench before the sensor's noise and resolution, and on a recorded trace
(:meth:`~drillgym.envs.effects.base.Effect.apply_to_trace`) for a fit that need not re-simulate.
"""

from __future__ import annotations

import math
from typing import Any

import numba
import numpy as np

from drillgym.envs.effects.base import Effect, EffectHost, Param, TraceView
from drillgym.envs.record_fields import float_field


class FTDrift(Effect):
    """F/T force drift: the strain gauges warm up and the tared zero walks away linearly in time.

    ``F_read = F + r · t`` per force axis, t the time since the tare at reset (s), r in N/s. Torques
    are left alone (their drift is a separate calibration). An ATI Mini40 drifts by ~0.1–1 % of its
    range (40–120 N) over minutes after power-up: up to a few 0.01 N/s.
    """

    name = "ft_drift"
    summary = "F/T force zero drifting linearly in time after the tare"
    params = (
        Param("fx_rate_n_s", -0.05, 0.05, 0.0, "drift rate of Fx (N/s, sensor frame)"),
        Param("fy_rate_n_s", -0.05, 0.05, 0.0, "drift rate of Fy (N/s, sensor frame)"),
        Param("fz_rate_n_s", -0.05, 0.05, 0.0, "drift rate of Fz (N/s, sensor frame)"),
    )
    channels = frozenset({"force"})
    channels_before_contact = frozenset({"force"})
    sensor_only = True
    compiled = True
    kernel_params = (
        float_field("ft_drift_rate_n_s", "F/T drift: the force axes' drift rates (N/s, sensor frame; 0: off).", 3),
    )

    def _rates(self) -> np.ndarray:
        v = self.values
        return np.array([v["fx_rate_n_s"], v["fy_rate_n_s"], v["fz_rate_n_s"]])

    def set_kernel_params(self, p: np.void) -> None:
        """The three rates (the compiled step adds ``rate · t`` to each force axis before the sensor's noise)."""
        p["ft_drift_rate_n_s"] = self._rates()

    def sensor_wrenches(self, env: EffectHost, wrenches: np.ndarray, t_s: np.ndarray) -> np.ndarray:
        """Add the drift to the force axes."""
        out = np.array(wrenches, dtype=float)
        out[:, :3] += self._rates()[None, :] * np.asarray(t_s)[:, None]
        return out

    def apply_to_trace(self, trace: TraceView) -> None:
        """Add the drift to the recorded forces."""
        trace.force_n += self._rates()[None, :] * trace.t_s[:, None]


@numba.njit(cache=True)
def drifted(rate: Any, t_s: float, f0: float, f1: float, f2: float) -> tuple[float, float, float]:  # pragma: no cover
    """:meth:`FTDrift.sensor_wrenches` in the compiled step: the drifted force axes (N).

    ``F + r · t`` per axis, ``t`` the sample's time since the tare at reset (s), ``rate`` the episode's
    ``ft_drift_rate_n_s`` (N/s, sensor frame).
    """
    return f0 + rate[0] * t_s, f1 + rate[1] * t_s, f2 + rate[2] * t_s


class FTEpisodeDrift(FTDrift):
    """F/T force drift whose rate differs from episode to episode around a shared mean.

    ``F_read = F + r_e · t`` as :class:`FTDrift`, with r_e the episode's own rates: a sensor re-powered or
    re-tared between holes, or a cable that lies differently each time, starts each episode at another point
    of its warm-up. In the simulator the parameters are one episode's rates; the diagnosis fits them per
    episode as a random effect ``r_e ~ N(r̄, τ²)`` (:mod:`drillgym.eval.diagnosis.random_effects`).
    """

    name = "ft_episode_drift"
    summary = "F/T force zero drifting linearly in time, at a rate of its own in each episode"
    per_episode = True
    variant_of = "ft_drift"


class FTGain(Effect):
    """F/T calibration error: the lateral and axial forces read with a wrong gain, the lateral ones with some thrust.

    ``F_read = C F`` with ``C = [[1 + g_xy, 0, c_x], [0, 1 + g_xy, c_y], [0, 0, 1 + g_z]]`` (sensor frame): the force
    rows of a calibration matrix off in their gains and in the cross-talk from the axial force, the one a
    drilling load makes visible (the thrust is tens of newtons, the lateral forces a few). Torques are left alone
    (their rows of the calibration matrix are separate). A wrong calibration file, a sensor recalibrated in
    another mounting, or a wrong counts-per-force setting scales whole rows; a sensor remounted with a tilted
    or preloaded adapter, or an overloaded one, reads a share of one axis on another. An ATI calibration is good
    to ~1–2 % of full scale (cross-talk included), a wrong file or unit by tens of per cent. Unlike a drift it
    changes nothing before contact, where the tared force is zero.
    """

    name = "ft_gain"
    summary = "F/T forces read through a wrong calibration: lateral and axial gains, thrust read laterally"
    params = (
        Param("fxy_gain", -0.5, 0.5, 0.0, "relative gain error of Fx and Fy (-)"),
        Param("fz_gain", -0.5, 0.5, 0.0, "relative gain error of Fz (-)"),
        Param("fx_from_fz", -0.05, 0.05, 0.0, "share of Fz read as Fx: cross-talk (-)"),
        Param("fy_from_fz", -0.05, 0.05, 0.0, "share of Fz read as Fy: cross-talk (-)"),
    )
    channels = frozenset({"force"})
    sensor_only = True

    def matrix(self) -> np.ndarray:
        """The force rows of the calibration error, ``C`` (3x3): ``F_read = C F``."""
        v = self.values
        gxy, gz = 1.0 + v["fxy_gain"], 1.0 + v["fz_gain"]
        return np.array([[gxy, 0.0, v["fx_from_fz"]], [0.0, gxy, v["fy_from_fz"]], [0.0, 0.0, gz]])

    def sensor_wrenches(self, env: EffectHost, wrenches: np.ndarray, t_s: np.ndarray) -> np.ndarray:
        """Read the forces through ``C``."""
        out = np.array(wrenches, dtype=float)
        out[:, :3] = out[:, :3] @ self.matrix().T
        return out

    def apply_to_trace(self, trace: TraceView) -> None:
        """Read the recorded forces through ``C``."""
        trace.force_n[:] = trace.force_n @ self.matrix().T


def engaged_share(env: EffectHost, n: int) -> np.ndarray:
    """Share of the lips' length in bone at the step's last ``n`` recorded samples (from the true tip), in [0, 1]."""
    cell = env.cell
    tips = np.asarray(env.recorder.tip_task_m[-n:], dtype=float)
    depth = tips[:, 2] + tips[:, 0] * cell.solver.tan_beta
    return np.clip(np.interp(depth, cell.table.depth_m, cell.table.engaged_fraction), 0.0, 1.0)


class FTContactBias(Effect):
    """F/T bias that appears at contact: the force reading shifts by ``s · b`` while the lips cut.

    ``F_read = F + s b`` (b per force axis in N, sensor frame; s the engaged share of the lips, 0 before
    contact and after the drill leaves). A load that reaches the strain gauges only while the tool is
    loaded: a cable or a spindle hose pulled as the arm pushes, a preloaded mount that seats under thrust,
    the spindle's heat flowing into the sensor while it cuts. Torques are left alone. Unlike a drift it reads
    nothing before contact, and unlike a gain it does not grow with the cutting force.
    """

    name = "ft_contact_bias"
    summary = "F/T force offset present only while the drill cuts (proportional to the engaged share)"
    params = (
        Param("bx_n", -3.0, 3.0, 0.0, "bias of Fx at full engagement (N, sensor frame)"),
        Param("by_n", -3.0, 3.0, 0.0, "bias of Fy at full engagement (N, sensor frame)"),
        Param("bz_n", -3.0, 3.0, 0.0, "bias of Fz at full engagement (N, sensor frame)"),
    )
    channels = frozenset({"force"})
    sensor_only = True

    def _bias(self) -> np.ndarray:
        v = self.values
        return np.array([v["bx_n"], v["by_n"], v["bz_n"]])

    def sensor_wrenches(self, env: EffectHost, wrenches: np.ndarray, t_s: np.ndarray) -> np.ndarray:
        """Add the engaged share times the bias to the force axes."""
        out = np.array(wrenches, dtype=float)
        out[:, :3] += engaged_share(env, len(t_s))[:, None] * self._bias()[None, :]
        return out

    def apply_to_trace(self, trace: TraceView) -> None:
        """Add the bias to the recorded forces, with the trace's engaged share."""
        trace.force_n += np.clip(trace.engaged_share, 0.0, 1.0)[:, None] * self._bias()[None, :]


RUNOUT_STIFFNESS_N_M = 5.0e3
"""Radial force per metre of runout (N/m): the hole wall forces the orbiting tip back toward the axis
through the drill's and the lips' lateral stiffness in series (drill 1.65 N/mm, lips ~10 N/mm)."""


class ToolRunout(Effect):
    """Tool runout: the drill tip orbits the spindle axis at radius e, so one lip cuts more.

    The chip imbalance makes a radial force of amplitude ``k · e · s`` (k
    :data:`RUNOUT_STIFFNESS_N_M`, s the engaged share of the lips) that turns with the spindle:
    ``F = A (cos ωt, sin ωt, 0)`` at the tip (ω the spindle speed in rad/s). The F/T samples it at
    100 Hz, so it appears aliased (333 Hz → 33 Hz at 20,000 rpm) in Fx, Fy and, through the arm L to the
    tip, in Tx = −L Fy and Ty = L Fx. The cycle-averaged physics is unchanged. Typical runout of a
    surgical chuck: 10–50 µm.
    """

    name = "tool_runout"
    summary = "drill runout: a once-per-revolution radial force, aliased into the F/T samples"
    params = (Param("runout_m", 0.0, 60e-6, 0.0, "radius of the tip's orbit about the spindle axis (m)"),)
    channels = frozenset({"force", "torque"})
    sensor_only = True

    def _rotating(self, t_s: np.ndarray, share: np.ndarray, rpm: float) -> np.ndarray:
        amp = RUNOUT_STIFFNESS_N_M * self.values["runout_m"] * np.clip(share, 0.0, 1.0)
        angle = 2.0 * math.pi * rpm / 60.0 * np.asarray(t_s)
        return np.stack([amp * np.cos(angle), amp * np.sin(angle)], axis=1)

    def sensor_wrenches(self, env: EffectHost, wrenches: np.ndarray, t_s: np.ndarray) -> np.ndarray:
        """Add the rotating force (and its moment about the sensor) to the step's samples."""
        f = self._rotating(t_s, engaged_share(env, len(t_s)), env.scenario.spindle_rpm)
        out = np.array(wrenches, dtype=float)
        arm = env.cell.sensor_arm_m
        out[:, 0] += f[:, 0]
        out[:, 1] += f[:, 1]
        out[:, 3] += -arm * f[:, 1]
        out[:, 4] += arm * f[:, 0]
        return out

    def apply_to_trace(self, trace: TraceView) -> None:
        """Add the rotating force to the recorded forces and torques."""
        f = self._rotating(trace.t_s, trace.engaged_share, trace.spindle_rpm)
        trace.force_n[:, :2] += f
        trace.torque_nm[:, 0] += -trace.sensor_arm_m * f[:, 1]
        trace.torque_nm[:, 1] += trace.sensor_arm_m * f[:, 0]
