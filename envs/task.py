"""The drilling task: the nominal path along the planned axis and its phases.

The path belongs to the task, not to the policy: approach from 3 mm above the planned entry point,
hand over to the drilling feed 0.2 mm before it, feed to the target depth at the (overridable) feed
rate, then retract. The nominal tip position is ``(0, 0, s)`` in the task frame, ``s`` the depth along
the planned axis (negative above the entry point).
"""

from __future__ import annotations

from enum import IntEnum

from drillgym.envs.constants import APPROACH_SPEED_M_S, APPROACH_START_M, FEED_START_M, RETRACT_SPEED_M_S
from drillgym.envs.read_through import ReadThrough


class Phase(IntEnum):
    """Where on the nominal path the task is."""

    APPROACH = 0
    FEED = 1
    RETRACT = 2
    DONE = 3


class DrillPath(ReadThrough):
    """Nominal approach → feed → retract path along the planned axis (task frame)."""

    def __init__(self, depth_m: float, feed_m_s: float) -> None:
        self.depth_m = depth_m
        self.feed_m_s = feed_m_s
        self.reset()

    def reset(self) -> None:
        """Back to the start of the approach."""
        self.s_m = -APPROACH_START_M
        self.phase = Phase.APPROACH

    def nominal_duration_s(self) -> float:
        """Duration of the whole path at the nominal feed (s)."""
        approach = (APPROACH_START_M - FEED_START_M) / APPROACH_SPEED_M_S
        feed = (self.depth_m + FEED_START_M) / self.feed_m_s
        retract = (self.depth_m + APPROACH_START_M) / RETRACT_SPEED_M_S
        return approach + feed + retract

    def speed_m_s(self, feed_scale: float) -> float:
        """Current path speed along the axis (m/s, positive into the bone)."""
        if self.phase == Phase.APPROACH:
            return APPROACH_SPEED_M_S
        if self.phase == Phase.FEED:
            return self.feed_m_s * feed_scale
        if self.phase == Phase.RETRACT:
            return -RETRACT_SPEED_M_S
        return 0.0

    def advance(self, dt_s: float, feed_scale: float = 1.0) -> float:
        """Move along the path for ``dt_s`` and return the new nominal depth ``s`` (m)."""
        self.s_m += self.speed_m_s(feed_scale) * dt_s
        if self.phase == Phase.APPROACH and self.s_m >= -FEED_START_M:
            self.phase = Phase.FEED
        elif self.phase == Phase.FEED and self.s_m >= self.depth_m:
            self.s_m = self.depth_m
            self.phase = Phase.RETRACT
        elif self.phase == Phase.RETRACT and self.s_m <= -APPROACH_START_M:
            self.s_m = -APPROACH_START_M
            self.phase = Phase.DONE
        return self.s_m

    @property
    def progress(self) -> float:
        """Fraction of the way along approach + feed + retract, in [0, 1]."""
        span = self.depth_m + APPROACH_START_M
        if self.phase in (Phase.APPROACH, Phase.FEED):
            return 0.5 * (self.s_m + APPROACH_START_M) / span
        if self.phase == Phase.RETRACT:
            return 0.5 + 0.5 * (self.depth_m - self.s_m) / span
        return 1.0
