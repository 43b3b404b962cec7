"""Sensor-side candidate effect: the F/T reads the wrench through a lightly damped structural mode."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from drillgym.envs.constants import PHYSICS_DT_S
from drillgym.envs.effects.base import Effect, EffectHost, Param, TraceView


def mode_filter(freq_hz: float, damping: float, dt_s: float = PHYSICS_DT_S) -> tuple[np.ndarray, np.ndarray]:
    """``(b, a)`` of the unit-gain mode ``ω² / (s² + 2ζω s + ω²)`` sampled every ``dt_s`` with the input held.

    Exact for a wrench held over the interval that *ends* at its sample, which is how the cell's 100 Hz samples
    are meant (the balance the drill reaches over the interval): the reading at a sample already holds its
    wrench's first response. This is the zero-order-hold discretisation advanced by one sample (its numerator
    shifted one tap earlier); the plain one reads each wrench one sample late, a 10 ms delay of its own.
    """
    from scipy import signal  # 1.3 s to import: only where a resonance is built

    w = 2.0 * math.pi * freq_hz
    b, a, _ = signal.cont2discrete(([w * w], [1.0, 2.0 * damping * w, w * w]), dt_s, method="zoh")
    b = np.ravel(b)
    return np.append(b[1:], 0.0), np.ravel(a)


LATERAL = np.array([True, True, False, True, True, False])
"""Wrench axes (Fx, Fy, Fz, Tx, Ty, Tz) the bending mode carries; the others (Fz, Tz) the axial one."""


class FTResonance(Effect):
    """Structural modes between the wrench and the sensor: the reading rings after every change of the load.

    ``W_read = W + a (H W − W)``, ``H`` a second-order mode of unit gain at rest (a steady wrench reads true):
    of frequency ``f_lat`` on the lateral axes (Fx, Fy, Tx, Ty: the mount bending) and ``f_ax`` on the axial
    ones (Fz, Tz: the mount stretching and twisting), both with damping ζ; ``a`` is the modes' share of the
    reading (1: the sensor sees the wrench only through them). A tool and spindle on a compliant mount, an arm
    link or a clamp ring at 10–40 Hz with ζ ~ 0.02–0.2, its bending and axial modes apart (a beam is far
    stiffer along its axis): the contact, a stage change or a feed step then reads as a ringing force, and a
    fast change as a lagging one. Nothing before contact (no load, nothing to ring).
    """

    name = "ft_resonance"
    summary = "F/T readings ring through a lightly damped bending and axial mode after each change of the load"
    params = (
        Param("amplitude", 0.0, 1.0, 0.0, "share of the reading that passes through the modes (-)"),
        Param("freq_lateral_hz", 5.0, 45.0, 20.0, "bending mode (Hz; Fx, Fy, Tx, Ty), below the F/T's 50 Hz Nyquist"),
        Param("freq_axial_hz", 5.0, 45.0, 20.0, "axial mode (Hz; Fz, Tz), below the F/T's 50 Hz Nyquist"),
        Param("damping", 0.02, 0.7, 0.1, "damping ratio of both modes (-)"),
    )
    channels = frozenset({"force", "torque"})
    sensor_only = True

    @classmethod
    def initial_guess(cls, evidence: dict[str, Any]) -> dict[str, float] | None:
        """Each mode at the frequency where its force residuals ring most (half the reading through them).

        A group with no ringing of its own starts where all three axes ring most.
        """
        peaks = evidence.get("excess_peaks_hz") or {}
        every = peaks.get("all")
        if every is None:
            return None
        low, high = cls.params[1].low, cls.params[1].high

        def at(group: str) -> float:
            f = peaks.get(group)
            return min(max(float(every if f is None else f), low), high)

        return {"amplitude": 0.5, "freq_lateral_hz": at("lateral"), "freq_axial_hz": at("axial"), "damping": 0.1}

    def _filters(self) -> tuple[tuple[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]:
        v = self.values
        return mode_filter(v["freq_lateral_hz"], v["damping"]), mode_filter(v["freq_axial_hz"], v["damping"])

    def attach(self, env: EffectHost) -> None:
        """The modes at rest, their filters made once for the episode's steps."""
        self.state = np.zeros((2, 6))
        self.filters = self._filters()

    @staticmethod
    def _ring(filters: Any, w: np.ndarray, state: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``H w`` of wrench rows (n, 6) from the modes' ``state`` (2, 6), and their state after the rows."""
        from scipy.signal import lfilter  # see mode_filter

        y, after = np.empty_like(w), np.empty_like(state)
        for (b, a), cols in zip(filters, (LATERAL, ~LATERAL), strict=True):
            y[:, cols], after[:, cols] = lfilter(b, a, w[:, cols], axis=0, zi=state[:, cols])
        return y, after

    def sensor_wrenches(self, env: EffectHost, wrenches: np.ndarray, t_s: np.ndarray) -> np.ndarray:
        """The step's samples through the modes, their state carried to the next step."""
        amp = self.values["amplitude"]
        w = np.asarray(wrenches, dtype=float)
        if amp == 0.0:
            return w
        y, self.state = self._ring(self.filters, w, self.state)
        return w + amp * (y - w)

    def apply_to_trace(self, trace: TraceView) -> None:
        """The recorded wrench through the modes, from rest at the first sample."""
        amp = self.values["amplitude"]
        if amp == 0.0:
            return
        w = np.concatenate([trace.force_n, trace.torque_nm], axis=1)
        y, _ = self._ring(self._filters(), w, np.zeros((2, 6)))
        w += amp * (y - w)
        trace.force_n[:] = w[:, :3]
        trace.torque_nm[:] = w[:, 3:]
