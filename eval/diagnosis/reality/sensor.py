"""Reality: F/T drift, calibration error and loaded bias, a wobbling runout, and a smoothing tracker.

Forms unlike the candidates' linear drift, per-axis gain, clean once-per-revolution force,
engagement-proportional bias and pure tracker delay.
"""

from __future__ import annotations

import math
from typing import ClassVar

import numpy as np

from drillgym.envs.effects.base import EffectHost, Param
from drillgym.eval.diagnosis.reality.base import RealityEffect


class FTWarmup(RealityEffect):
    """F/T warm-up: the zero settles exponentially after power-up.

    Drift ``A (e^{−t₀/τ} − e^{−(t₀+t)/τ})`` since the tare, t₀ the (random, 0–60 s) time the sensor had been
    on at the tare (τ a few minutes: nearly, not exactly, linear over an episode); torques drift by 2 %
    of the forces' amount times 5 mm.
    """

    name = "ft_warmup"
    summary = "F/T zero settling exponentially after power-up"
    explains = "ft_drift"
    params: ClassVar[tuple[Param, ...]] = (
        Param("fx_n", -10.0, 10.0, 0.0, "asymptotic drift of Fx (N)"),
        Param("fy_n", -10.0, 10.0, 0.0, "asymptotic drift of Fy (N)"),
        Param("fz_n", -10.0, 10.0, 0.0, "asymptotic drift of Fz (N)"),
        Param("tau_s", 5.0, 900.0, 300.0, "settling time constant (s)"),
    )
    channels = frozenset({"force", "torque"})

    def attach(self, env: EffectHost) -> None:
        """Draw how long the sensor had been on."""
        self.on_s = float(self.rng.uniform(0.0, 60.0))
        v = self.values
        self.amp_n = np.array([v["fx_n"], v["fy_n"], v["fz_n"]])

    def sensor_wrenches(self, env: EffectHost, wrenches: np.ndarray, t_s: np.ndarray) -> np.ndarray:
        """Add the settling drift."""
        tau = self.values["tau_s"]
        shape = math.exp(-self.on_s / tau) - np.exp(-(self.on_s + np.asarray(t_s)) / tau)
        out = np.array(wrenches, dtype=float)
        out[:, :3] += shape[:, None] * self.amp_n[None, :]
        out[:, 3:] += 0.02 * 0.005 * shape[:, None] * self.amp_n[None, :]
        return out

    def candidate_values(self) -> dict[str, float] | None:
        """The linear drift's (mean) rates: the slope at the tare ``A/τ · e^{−t₀/τ}``, averaged over t₀ ~ U(0, 60 s)."""
        v = self.values
        tau = v["tau_s"]
        mean_decay = tau / 60.0 * (1.0 - math.exp(-60.0 / tau))
        return {f"f{a}_rate_n_s": v[f"f{a}_n"] / tau * mean_decay for a in "xyz"}


class FTEpisodeWarmup(FTWarmup):
    """F/T warm-up whose amount and sign differ from episode to episode.

    The settling drift of :class:`FTWarmup`, with each episode's asymptotic drift per force axis drawn
    around the mean: ``A_e = A + spread · N(0, 1)`` (a sensor re-powered between holes, a cable that lies
    differently each time). With a zero mean a drift fitted once for all episodes comes out near zero;
    the candidate ``ft_episode_drift`` fits a linear rate per episode around a shared mean.
    """

    name = "episode_warmup"
    summary = "F/T zero settling after power-up, by an amount and sign of its own in each episode"
    explains = "ft_episode_drift"
    params = (*FTWarmup.params, Param("spread_n", 0.0, 10.0, 0.0, "episode-to-episode standard deviation of A (N)"))

    def attach(self, env: EffectHost) -> None:
        """Draw the sensor's time on and this episode's drift."""
        super().attach(env)
        self.amp_n = self.amp_n + self.values["spread_n"] * self.rng.standard_normal(3)

    def episode_candidate_values(self) -> dict[str, float] | None:
        """This episode's rates: the drift's slope at the tare, ``A_e / τ · e^{−t₀/τ}``."""
        slope = self.amp_n / self.values["tau_s"] * math.exp(-self.on_s / self.values["tau_s"])
        return {f"f{a}_rate_n_s": float(r) for a, r in zip("xyz", slope, strict=True)}


class FTLateralGain(RealityEffect):
    """A calibration error of the F/T's lateral axes: a gain and a cross-talk from the axial force.

    ``Fx_read = (1 + gain) Fx + crosstalk · Fz``, ``Fy_read = (1 + gain) Fy`` (a calibration matrix whose
    x row is off, as after remounting the sensor). The candidate ``ft_gain`` (lateral and axial gains, cross-talk
    from Fz into Fx and Fy) has this form and more; it is opt-in (``docs/diagnosis.md`` §3), so with the default
    candidates this effect should come out unexplained, located at the lateral forces. Unlike a drift it changes
    nothing before contact, where the tared force is zero: a drift named for it predicts a force there that the
    data do not show.
    """

    name = "ft_lateral_gain"
    summary = "F/T lateral axes reading with a wrong gain and some of the thrust (calibration error)"
    explains = "ft_gain"
    params = (
        Param("gain", -0.5, 0.5, 0.0, "relative gain error of Fx and Fy (-)"),
        Param("crosstalk", -0.05, 0.05, 0.0, "share of Fz read as Fx (-)"),
    )
    channels = frozenset({"force"})

    def sensor_wrenches(self, env: EffectHost, wrenches: np.ndarray, t_s: np.ndarray) -> np.ndarray:
        """Scale the lateral forces and add the cross-talk."""
        out = np.array(wrenches, dtype=float)
        out[:, :2] *= 1.0 + self.values["gain"]
        out[:, 0] += self.values["crosstalk"] * out[:, 2]
        return out

    def candidate_values(self) -> dict[str, float] | None:
        """``ft_gain``'s matrix: the lateral gain and the x row's cross-talk, the rest true."""
        v = self.values
        return {"fxy_gain": v["gain"], "fz_gain": 0.0, "fx_from_fz": v["crosstalk"], "fy_from_fz": 0.0}


class WobblyRunout(RealityEffect):
    """A tilted drill's runout with a spindle whose speed ripples.

    The once-per-revolution force has a random phase, a wandering frequency and grows with the engaged
    share to the power 1.5.
    """

    name = "wobbly_runout"
    summary = "runout force with random phase, speed ripple and a nonlinear engagement law"
    explains = "tool_runout"
    params = (
        Param("runout_m", 0.0, 60e-6, 0.0, "tip orbit radius (m)"),
        Param("stiffness_n_m", 1e3, 2e4, 6e3, "radial force per metre of runout (N/m)"),
        Param("speed_ripple", 0.0, 0.05, 0.01, "spindle speed ripple (fraction, 0.7 Hz)"),
    )
    channels = frozenset({"force", "torque"})

    def attach(self, env: EffectHost) -> None:
        """Random phase of the orbit."""
        self.phase0 = float(self.rng.uniform(0.0, 2 * math.pi))

    def sensor_wrenches(self, env: EffectHost, wrenches: np.ndarray, t_s: np.ndarray) -> np.ndarray:
        """Add the orbiting force and its moment."""
        v = self.values
        cell = env.cell
        t = np.asarray(t_s)
        omega = 2 * math.pi * env.scenario.spindle_rpm / 60.0
        ripple = v["speed_ripple"] * omega / (2 * math.pi * 0.7) * (1 - np.cos(2 * math.pi * 0.7 * t))
        angle = self.phase0 + omega * t + ripple
        tips = np.asarray(env.recorder.tip_task_m[-t.size :], dtype=float)
        share = np.interp(
            tips[:, 2] + tips[:, 0] * cell.solver.tan_beta, cell.table.depth_m, cell.table.engaged_fraction
        )
        amp = v["stiffness_n_m"] * v["runout_m"] * np.clip(share, 0.0, 1.0) ** 1.5
        fx, fy = amp * np.cos(angle), amp * np.sin(angle)
        out = np.array(wrenches, dtype=float)
        arm = cell.sensor_arm_m
        out[:, 0] += fx
        out[:, 1] += fy
        out[:, 3] -= arm * fy
        out[:, 4] += arm * fx
        return out

    def candidate_values(self) -> dict[str, float] | None:
        """``tool_runout``'s orbit radius is this one (at full engagement both laws give ``k e``)."""
        return {"runout_m": self.values["runout_m"]}


class FTLoadBias(RealityEffect):
    """An F/T offset loaded by the thrust: ``F_read = F + b tanh(|F_z| / F₀)`` on each force axis.

    The offset comes with the axial load (a hose or cable pulled, a mount seating as the arm pushes) and
    saturates above F₀; it goes when the thrust does. The candidate ``ft_contact_bias`` has it follow the
    engaged share of the lips instead: the two agree in the stable cut and differ at entry and exit.
    """

    name = "ft_load_bias"
    summary = "F/T force offset loaded by the thrust (saturating in |Fz|)"
    explains = "ft_contact_bias"
    params = (
        Param("bx_n", -3.0, 3.0, 0.0, "saturated bias of Fx (N, sensor frame)"),
        Param("by_n", -3.0, 3.0, 0.0, "saturated bias of Fy (N, sensor frame)"),
        Param("bz_n", -3.0, 3.0, 0.0, "saturated bias of Fz (N, sensor frame)"),
        Param("load_n", 0.2, 10.0, 1.5, "thrust at which the bias reaches 76 % (tanh 1) of its saturated value (N)"),
    )
    channels = frozenset({"force"})

    def sensor_wrenches(self, env: EffectHost, wrenches: np.ndarray, t_s: np.ndarray) -> np.ndarray:
        """Add the thrust-loaded bias."""
        v = self.values
        out = np.array(wrenches, dtype=float)
        load = np.tanh(np.abs(out[:, 2]) / v["load_n"])
        out[:, :3] += load[:, None] * np.array([v["bx_n"], v["by_n"], v["bz_n"]])[None, :]
        return out

    def candidate_values(self) -> dict[str, float] | None:
        """``ft_contact_bias``'s bias at full engagement is the saturated one."""
        v = self.values
        return {"bx_n": v["bx_n"], "by_n": v["by_n"], "bz_n": v["bz_n"]}


class TrackerSmoothing(RealityEffect):
    """A tracker whose pose filter smooths the marker: a first-order low-pass with time constant τ.

    Each reading moves toward the marker's position by ``1 − e^{−Δt/τ}`` of the distance (Δt the time
    since the previous reading). At a steady speed it lags by τ, like a delay; where the speed changes
    (approach to feed, the retract, a correction) it rounds the motion instead of shifting it. The candidate
    ``tracker_latency`` is a pure delay.
    """

    name = "tracker_smoothing"
    summary = "tracker pose filter: first-order low-pass of the marker position"
    explains = "tracker_latency"
    params = (Param("tau_s", 0.0, 0.3, 0.0, "time constant of the pose filter (s)"),)
    channels = frozenset({"tracker"})

    def attach(self, env: EffectHost) -> None:
        """No filtered reading yet."""
        self._filtered: np.ndarray | None = None
        self._marker = np.zeros(3)
        self._stamp_s = 0.0

    def tracker_marker_base_m(self, env: EffectHost, marker_base_m: np.ndarray, stamp_s: float) -> np.ndarray:
        """Run the filter from the previous reading to this one and report its output.

        The marker is taken to move at a constant velocity between the two readings; the filter's answer to
        that ramp is exact (``y' = (x − y) / τ``), so the filter runs in continuous time whatever the reading rate.
        """
        tau = self.values["tau_s"]
        if tau <= 0.0:
            return marker_base_m
        x1 = np.asarray(marker_base_m, dtype=float)
        if self._filtered is None:
            self._filtered = x1.copy()
        else:
            dt = stamp_s - self._stamp_s
            ramp = (x1 - self._marker) / dt * tau if dt > 0.0 else np.zeros(3)
            self._filtered = x1 - ramp + (self._filtered - self._marker + ramp) * math.exp(-dt / tau)
        self._marker, self._stamp_s = x1, stamp_s
        return self._filtered.copy()

    def candidate_values(self) -> dict[str, float] | None:
        """``tracker_latency``'s delay is the filter's lag at a steady speed, its time constant."""
        return {"latency_s": self.values["tau_s"]}
