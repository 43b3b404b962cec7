"""The hole already cut, and how its wall guides the drill (lock-in of an early deviation)."""

from __future__ import annotations

import math

import numba
import numpy as np


@numba.njit(cache=True)
def cut(
    centre_xy: np.ndarray, filled: np.ndarray, bins: np.ndarray, bin_m: float, depth_m: float, x: float, y: float
) -> None:  # pragma: no cover (compiled)
    """Cut a hole's arrays to ``depth_m`` with the centre ``(x, y)`` (m, task xy): :meth:`Hole.record`, in place.

    ``bins`` is ``[deepest_bin, first_bin]``; nothing changes unless ``depth_m`` reaches a new bin.
    """
    k = int(depth_m / bin_m)
    if k <= bins[0] or k < 0:
        return
    k = min(k, filled.shape[0] - 1)
    lo = max(bins[0] + 1, 0)
    for b in range(lo, k + 1):
        centre_xy[b, 0] = x
        centre_xy[b, 1] = y
        filled[b] = True
    if bins[1] < 0:
        bins[1] = lo
    bins[0] = k


def centre_at(centre_xy: np.ndarray, bins: np.ndarray, bin_m: float, depth_m: float) -> np.ndarray | None:
    """A hole's centreline (m, task xy) at ``depth_m``, the first cut point above it; None before any cut.

    The arrays are :class:`Hole`'s (``bins``: ``[deepest_bin, first_bin]``), or a batched env's episode's.
    """
    deepest, first = int(bins[0]), int(bins[1])
    if deepest < 0:
        return None
    k = min(max(int(depth_m / bin_m), first), deepest)
    return centre_xy[k]


class Hole:
    """Centreline of the hole cut so far, sampled along the planned axis.

    Frame: the task frame (origin at the planned entry point, z along the planned axis into the bone).
    New hole is cut where the tip is; once the drill body is inside, the wall pushes the tip back
    toward the centreline cut ``guide_length_m`` behind it with stiffness ``k_wall · g``, where
    ``g ∈ [0, 1]`` is how much of the hole circumference exists (the outer-corner engagement). So a
    deviation made at entry is copied forward and relaxes only as fast as the wall can be cut sideways.
    """

    def __init__(self, max_depth_m: float, bin_m: float = 5e-6) -> None:
        self.bin_m = bin_m
        n = math.ceil(max_depth_m / bin_m) + 2
        self.centre_xy_m = np.zeros((n, 2))
        self.filled = np.zeros(n, dtype=bool)
        self.bins = np.array([-1, -1])
        """``[deepest_bin, first_bin]``: the deepest and the first bin cut (-1: none)."""

    @property
    def deepest_bin(self) -> int:
        """Index of the deepest bin cut (-1 before any cut)."""
        return int(self.bins[0])

    @property
    def first_bin(self) -> int:
        """Index of the first bin cut (-1 before any cut)."""
        return int(self.bins[1])

    def reset(self) -> None:
        """Uncut bone."""
        self.filled[:] = False
        self.bins[:] = -1

    def record(self, depth_m: float, tip_xy_m: np.ndarray) -> None:
        """Cut the hole to ``depth_m`` (along the planned axis) with its centre at ``tip_xy_m`` (:func:`cut`)."""
        cut(self.centre_xy_m, self.filled, self.bins, self.bin_m, depth_m, float(tip_xy_m[0]), float(tip_xy_m[1]))

    def centre_at(self, depth_m: float) -> np.ndarray | None:
        """Centreline (m, task xy) at ``depth_m``; the first cut point above it; None before any cut."""
        return centre_at(self.centre_xy_m, self.bins, self.bin_m, depth_m)

    def centre_below(self, depth_m: float) -> np.ndarray | None:
        """Centreline (m, task xy) at ``depth_m`` if the hole reaches that deep past its first cut, else None."""
        k = int(depth_m / self.bin_m)
        if self.deepest_bin < 0 or k < self.first_bin or k > self.deepest_bin:
            return None
        return self.centre_xy_m[k]

    def profile(self) -> tuple[np.ndarray, np.ndarray]:
        """Depths (m) and centres (m, task xy) of the cut bins, shallow to deep."""
        idx = np.flatnonzero(self.filled)
        return idx * self.bin_m, self.centre_xy_m[idx].copy()
