"""Resampling the real cell's streams onto the env's 100 Hz sample grid (the simulator's F/T rate).

F/T records arrive at the sensor's rate (hundreds to thousands per second); each 10 ms bin of the episode
clock gets their mean (a moving-average decimation), or holds the previous value if a bin got no record.
The nominal path (depth and phase) is known per servo cycle and is read at each bin's end.
"""

from __future__ import annotations

import bisect
from collections.abc import Sequence

import numpy as np

from drillgym.envs.constants import PHYSICS_DT_S
from drillgym.envs.real.netft import FTRecord


class FTBinner:
    """Means of F/T records per 10 ms bin of the episode clock, tared.

    Args:
        t0: episode start (``time.monotonic()``).
        bias: wrench subtracted from every record (the tare, N and N·m).
    """

    def __init__(self, t0: float, bias: np.ndarray) -> None:
        self.t0 = t0
        self.bias = np.asarray(bias, dtype=float)
        self.next_bin = 0
        self.last = np.zeros(6)
        self.empty_bins = 0

    def bins_until(self, records: Sequence[FTRecord], t_end: float) -> tuple[list[float], np.ndarray]:
        """Close every bin ending at or before ``t_end`` (monotonic).

        Args:
            records: records that arrived since the start of the first open bin (oldest first).
            t_end: close bins up to here.

        Returns:
            Bin end times since the episode start (s) and the binned wrenches (n, 6).
        """
        times, values = [], []
        arrivals = [r.t_recv_s for r in records]
        while self.t0 + (self.next_bin + 1) * PHYSICS_DT_S <= t_end + 1e-9:
            lo_t = self.t0 + self.next_bin * PHYSICS_DT_S
            hi_t = lo_t + PHYSICS_DT_S
            lo, hi = bisect.bisect_left(arrivals, lo_t), bisect.bisect_left(arrivals, hi_t)
            if hi > lo:
                self.last = np.mean([records[i].wrench for i in range(lo, hi)], axis=0) - self.bias
            else:
                self.empty_bins += 1
            self.next_bin += 1
            times.append(self.next_bin * PHYSICS_DT_S)
            values.append(self.last)
        return times, np.asarray(values, dtype=float).reshape(len(values), 6)

    @property
    def open_bin_start(self) -> float:
        """Start of the first bin not yet closed (monotonic)."""
        return self.t0 + self.next_bin * PHYSICS_DT_S


def path_at(
    times_s: Sequence[float], hist_t: Sequence[float], hist_s: Sequence[float], hist_phase: Sequence[int]
) -> tuple[list[float], list[int]]:
    """Nominal depth (m, interpolated) and phase (the last cycle's) at each of ``times_s`` (s since start).

    The history is the servo stream's, one entry per cycle; before its first entry the first is used.
    """
    n = min(len(hist_t), len(hist_s), len(hist_phase))
    if n == 0:
        raise ValueError("no servo cycle recorded yet")
    t = np.asarray(hist_t[:n])
    depth = np.interp(times_s, t, np.asarray(hist_s[:n])).tolist()
    idx = np.clip(np.searchsorted(t, times_s, side="right") - 1, 0, n - 1)
    return depth, [int(hist_phase[i]) for i in idx]
