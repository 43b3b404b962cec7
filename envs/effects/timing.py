"""Timing candidate effect: extra control latency, a fixed delay of the whole servo target."""

from __future__ import annotations

import bisect

from drillgym.envs.effects.base import Effect, EffectHost, Param


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

    def attach(self, env: EffectHost) -> None:
        """Start an empty delay line."""
        self.line = DelayLine()

    def delay_target(self, t_s: float, target: tuple[float, float, float]) -> tuple[float, float, float]:
        """The target as it was ``extra_latency_s`` ago."""
        delay = self.values["extra_latency_s"]
        if delay <= 0.0:
            return target
        self.line.push(t_s, target)
        self.line.trim(t_s - delay - 0.05)
        return self.line.read(t_s - delay)
