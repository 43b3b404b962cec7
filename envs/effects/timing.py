"""Timing candidate effect: extra control latency, a fixed delay of the whole servo target."""

from __future__ import annotations

import bisect
from typing import Any

import numba
import numpy as np

from drillgym.envs.effects.base import Effect, EffectHost, Param
from drillgym.envs.record_fields import float_field, int_field


class DelayLine:
    """Samples of a 3-vector signal in time, read back ``delay_s`` late (linear interpolation).

    Before the first sample the first value is returned. Times must not decrease.
    """

    def __init__(self) -> None:
        self.t: list[float] = []
        self.v: list[tuple[float, float, float]] = []

    def push(self, t_s: float, value: tuple[float, float, float]) -> None:
        """Record ``value`` at ``t_s``."""
        self.t.append(t_s)
        self.v.append(value)

    def read(self, t_s: float) -> tuple[float, float, float]:
        """The signal at ``t_s`` (s), interpolated between recorded samples."""
        t, v = self.t, self.v
        if t_s <= t[0]:
            return v[0]
        j = bisect.bisect_right(t, t_s)
        if j >= len(t):
            return v[-1]
        a, b = v[j - 1], v[j]
        w = (t_s - t[j - 1]) / (t[j] - t[j - 1])
        return a[0] + w * (b[0] - a[0]), a[1] + w * (b[1] - a[1]), a[2] + w * (b[2] - a[2])

    def trim(self, before_s: float) -> None:
        """Forget samples older than ``before_s`` (keeping one before it for interpolation)."""
        j = bisect.bisect_left(self.t, before_s) - 1
        if j > 64:
            del self.t[:j]
            del self.v[:j]


class Latency(Effect):
    """Extra control latency: the servo follows its whole target (path + correction) ``Δ`` late.

    The cell already models Li's 14 ms command latency; this adds a fixed delay of the streamed target
    (network, controller cycle, a slower servo interface). A delay shows where the target moves: the
    approach, the feed, the retract, a correction; the RTDE joint angles and TCP lag by Δ · speed.
    """

    name = "latency"
    summary = "extra fixed delay of the streamed servo target"
    params = (Param("extra_latency_s", 0.0, 0.3, 0.0, "extra delay of the servo target (s)"),)
    channels = frozenset({"force", "torque", "tracker", "q", "tcp"})
    channels_before_contact = frozenset({"tracker", "q", "tcp"})
    compiled = True
    kernel_params = (float_field("extra_latency_s", "Extra delay of the whole servo target (s; 0: off)."),)
    kernel_state = (int_field("delay_count", "Samples held in the delay line ``delay`` (extra latency)."),)

    def attach(self, env: EffectHost) -> None:
        """Start an empty delay line."""
        self.line = DelayLine()

    def set_kernel_params(self, p: np.void) -> None:
        """The delay."""
        p["extra_latency_s"] = self.values["extra_latency_s"]

    def delay_target(self, t_s: float, target: tuple[float, float, float]) -> tuple[float, float, float]:
        """The target as it was ``extra_latency_s`` ago."""
        delay = self.values["extra_latency_s"]
        if delay <= 0.0:
            return target
        self.line.push(t_s, target)
        self.line.trim(t_s - delay - 0.05)
        return self.line.read(t_s - delay)


@numba.njit(cache=True)
def delayed(
    s: Any, delay: np.ndarray, t_s: float, x: float, y: float, z: float, delay_s: float
) -> tuple[float, float, float]:  # pragma: no cover (compiled)
    """The servo target (m, task frame) as it was ``delay_s`` before ``t_s``, after recording ``(x, y, z)`` at ``t_s``.

    :class:`DelayLine`'s ``push`` and ``read`` on an episode's delay line ``delay`` (rows ``t_s, x, y, z``; its
    ``s.delay_count`` rows in use): linear interpolation between samples, the first sample before it. When full,
    its newest half is kept.
    """
    n = s.delay_count
    if n == delay.shape[0]:  # full: keep the newest half
        keep = n // 2
        delay[:keep] = delay[n - keep : n].copy()
        n = keep
    delay[n, 0], delay[n, 1], delay[n, 2], delay[n, 3] = t_s, x, y, z
    n += 1
    s.delay_count = n
    t_read = t_s - delay_s
    if t_read <= delay[0, 0]:
        return delay[0, 1], delay[0, 2], delay[0, 3]
    j = np.searchsorted(delay[:n, 0], t_read, side="right")
    if j >= n:
        return delay[n - 1, 1], delay[n - 1, 2], delay[n - 1, 3]
    w = (t_read - delay[j - 1, 0]) / (delay[j, 0] - delay[j - 1, 0])
    a, b = delay[j - 1], delay[j]
    return a[1] + w * (b[1] - a[1]), a[2] + w * (b[2] - a[2]), a[3] + w * (b[3] - a[3])
