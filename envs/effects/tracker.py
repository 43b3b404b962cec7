"""Tracker candidate effect: a late tracker, whose marker position is reported some time after it was there."""

from __future__ import annotations

import numpy as np

from drillgym.envs.constants import SUBSTEPS_PER_STEP, TRACKER_RATE_HZ
from drillgym.envs.effects.base import Effect, EffectHost, Param, TraceView
from drillgym.envs.effects.timing import DelayLine


def step_tracker_stamps_s(t_s: np.ndarray) -> np.ndarray:
    """The time stamp (s) of the tracker reading each F/T sample of a recorded episode holds.

    The env reads the tracker once per agent step, at the step's last sample, and that reading is the
    newest one of the tracker's stream (:data:`drillgym.envs.constants.TRACKER_RATE_HZ`) at that time; it is
    held over the step's samples. ``t_s`` are the samples' times since reset (s), :data:`SUBSTEPS_PER_STEP`
    per step.
    """
    t = np.asarray(t_s, dtype=float)
    last = np.minimum((np.arange(t.size) // SUBSTEPS_PER_STEP + 1) * SUBSTEPS_PER_STEP - 1, t.size - 1)
    return np.floor(t[last] * TRACKER_RATE_HZ + 1e-9) / TRACKER_RATE_HZ


class TrackerLatency(Effect):
    """A late tracker: each reading reports where the marker was ``Δ`` before its time stamp.

    Optical trackers filter and transmit their pose: the reading arrives stamped on the PC's clock but
    describes the marker some tens of milliseconds earlier. Only the tracker channel changes, before
    contact too (the marker moves on the approach), by about Δ times the marker's speed: along the drill on
    the approach and the feed, across it where a correction moves the tool. The commands a controller took
    from the late readings are in the log, so a fit applies the delay to the recorded readings
    (:meth:`apply_to_trace`) instead of re-simulating.
    """

    name = "tracker_latency"
    summary = "tracker readings describing the marker a fixed time before their stamp"
    params = (Param("latency_s", 0.0, 0.3, 0.0, "age of the marker position a reading reports (s)"),)
    channels = frozenset({"tracker"})
    channels_before_contact = frozenset({"tracker"})
    sensor_only = True

    def attach(self, env: EffectHost) -> None:
        """Start an empty history of marker positions."""
        self._history = DelayLine()

    def tracker_marker_base_m(self, env: EffectHost, marker_base_m: np.ndarray, stamp_s: float) -> np.ndarray:
        """The marker position ``latency_s`` before ``stamp_s``, interpolated between the tracker's samples."""
        delay = self.values["latency_s"]
        if delay <= 0.0:
            return marker_base_m
        x, y, z = (float(v) for v in marker_base_m)
        self._history.push(stamp_s, (x, y, z))
        self._history.trim(stamp_s - delay - 1.0)
        return np.array(self._history.read(stamp_s - delay))

    def apply_to_trace(self, trace: TraceView) -> None:
        """Delay the recorded tracker readings (interpolated between the distinct readings' stamps)."""
        delay = self.values["latency_s"]
        if delay <= 0.0 or trace.tracker_m is None:
            return
        stamps = step_tracker_stamps_s(trace.t_s)
        ok = np.isfinite(trace.tracker_m).all(axis=1)
        if not ok.any():
            return
        t_known, first = np.unique(stamps[ok], return_index=True)
        values = trace.tracker_m[ok][first]
        for axis in range(3):
            trace.tracker_m[ok, axis] = np.interp(stamps[ok] - delay, t_known, values[:, axis])
