"""Sensor-side candidate effect: the F/T reads the wrench through a lightly damped structural mode."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from scipy import signal

from drillgym.envs.constants import PHYSICS_DT_S
from drillgym.envs.effects.base import Effect, EffectHost, Param, TraceView


def mode_filter(freq_hz: float, damping: float, dt_s: float = PHYSICS_DT_S) -> tuple[np.ndarray, np.ndarray]:
    """``(b, a)`` of the unit-gain mode ``ω² / (s² + 2ζω s + ω²)`` sampled every ``dt_s`` with the input held.

    The zero-order-hold discretisation: exact for a wrench constant between samples, which is how the cell's
    100 Hz samples are meant (one quasi-static balance per sample).
    """
    w = 2.0 * math.pi * freq_hz
    b, a, _ = signal.cont2discrete(([w * w], [1.0, 2.0 * damping * w, w * w]), dt_s, method="zoh")
    return np.ravel(b), np.ravel(a)


class FTResonance(Effect):
    """A structural mode between the wrench and the sensor: the reading rings after every change of the load.

    ``W_read = W + a (H W − W)`` on all six axes, ``H`` a second-order mode of frequency f and damping ζ
    (unit gain at rest, so a steady wrench reads true) and ``a`` its share of the reading (1: the sensor sees
    the wrench only through the mode). A tool and spindle on a compliant mount, an arm link or a clamp ring at
    10–40 Hz with ζ ~ 0.02–0.2: the contact, a stage change or a feed step then reads as a ringing force, and a
    fast change as a lagging one. Nothing before contact (no load, nothing to ring).
    """

    name = "ft_resonance"
    summary = "F/T readings ring through a lightly damped structural mode after each change of the load"
    params = (
        Param("amplitude", 0.0, 1.0, 0.0, "share of the reading that passes through the mode (-)"),
        Param("freq_hz", 5.0, 45.0, 20.0, "frequency of the mode (Hz), below the 50 Hz Nyquist limit of the F/T"),
        Param("damping", 0.02, 0.7, 0.1, "damping ratio of the mode (-)"),
    )
    channels = frozenset({"force", "torque"})
    sensor_only = True

    @classmethod
    def initial_guess(cls, evidence: dict[str, Any]) -> dict[str, float] | None:
        """The mode at the frequency where the force residuals ring most (half the reading through it)."""
        peak = evidence.get("excess_peak_hz")
        if peak is None:
            return None
        low, high = cls.params[1].low, cls.params[1].high
        return {"amplitude": 0.5, "freq_hz": min(max(float(peak), low), high), "damping": 0.1}

    def _filter(self) -> tuple[np.ndarray, np.ndarray]:
        return mode_filter(self.values["freq_hz"], self.values["damping"])

    def attach(self, env: EffectHost) -> None:
        """The mode at rest, its filter made once for the episode's steps."""
        self.state = np.zeros((2, 6))
        self.ba = self._filter()

    def sensor_wrenches(self, env: EffectHost, wrenches: np.ndarray, t_s: np.ndarray) -> np.ndarray:
        """The step's samples through the mode, its state carried to the next step."""
        amp = self.values["amplitude"]
        w = np.asarray(wrenches, dtype=float)
        if amp == 0.0:
            return w
        b, a = self.ba
        y, self.state = signal.lfilter(b, a, w, axis=0, zi=self.state)
        return w + amp * (y - w)

    def apply_to_trace(self, trace: TraceView) -> None:
        """The recorded wrench through the mode, from rest at the first sample."""
        amp = self.values["amplitude"]
        if amp == 0.0:
            return
        b, a = self._filter()
        for arr in (trace.force_n, trace.torque_nm):
            arr += amp * (signal.lfilter(b, a, arr, axis=0) - arr)
