"""Settings of the real-cell backend: safety limits and servo parameters, SI units, defaults in code."""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

from drillgym.envs.constants import MAX_CORRECTION_M, RTDE_RATE_HZ
from drillgym.envs.errors import UserError


@dataclass(frozen=True)
class SafetyLimits:
    """Limits the real env enforces on top of the robot's own safety system.

    Workspace box (task frame: origin at the planned entry point, z along the drill into the bone): a servo
    target or a measured TCP outside it stops the episode. Corrections beyond ``max_correction_m`` per base
    axis are clipped; the target moves no faster than ``max_tcp_speed_m_s`` (rate-limited, not stopped).
    Force limit: ``scenario.force_limit_n`` (the same argument as the simulated env).
    """

    workspace_lateral_m: float = 6e-3
    """Largest |x| and |y| of the target or TCP in the task frame (m)."""
    workspace_above_m: float = 20e-3
    """Highest point above the entry along the axis (m)."""
    workspace_below_m: float = 2e-3
    """Deepest point past the planned depth (m)."""
    max_correction_m: float = MAX_CORRECTION_M
    """Clip on the commanded correction per base axis (m)."""
    max_tcp_speed_m_s: float = 0.05
    """Largest speed of the servo target (m/s): faster changes are spread over several cycles."""
    max_tracking_error_m: float = 3e-3
    """Largest distance between the measured TCP and the servo target (m)."""
    max_cycle_gap_s: float = 0.1
    """Longest time between two servo commands (s); more is a watchdog stop. The robot's own RTDE watchdog
    (``setWatchdog``, armed at every reset) stops the program after twice this: :attr:`robot_watchdog_hz`."""
    rtde_stale_s: float = 0.1
    """Longest time without a new RTDE state (its timestamp not advancing) (s)."""
    ft_stale_s: float = 0.1
    """Longest time without an F/T record (s)."""
    tracker_stale_s: float = 0.1
    """A tracker reading older than this is not valid (``tracker_valid`` = 0; not a stop) (s)."""
    agent_timeout_s: float = 1.0
    """Longest time between two ``step()`` calls while streaming (s)."""
    reset_max_distance_m: float = 0.05
    """``reset`` refuses to move if the TCP is farther than this from the start pose (m): jog it closer first."""
    reset_max_angle_rad: float = math.radians(5.0)
    """... or if its orientation differs more than this from the planned drill axis (rad)."""
    approach_speed_m_s: float = 0.01
    """Speed of the ``moveL`` to the start pose (m/s)."""

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
                raise UserError(f"SafetyLimits.{f.name}={value!r} must be a positive finite number")
        if self.max_correction_m > MAX_CORRECTION_M:
            raise UserError(f"max_correction_m={self.max_correction_m} exceeds the action scale {MAX_CORRECTION_M}")

    @property
    def robot_watchdog_hz(self) -> float:
        """Minimum input rate of the robot-side RTDE watchdog (Hz).

        A pause of ``2 · max_cycle_gap_s`` stops the program, so the env's own check (with a precise reason)
        always comes first.
        """
        return 1.0 / (2.0 * self.max_cycle_gap_s)


@dataclass(frozen=True)
class ServoParams:
    """``servoL`` streaming parameters (UR's servo semantics)."""

    rate_hz: float = RTDE_RATE_HZ
    """Streaming rate (Hz): the CB3 controller's 125 Hz."""
    lookahead_time_s: float = 0.1
    """``servoL`` lookahead (s, UR range [0.03, 0.2]): smooths the trajectory."""
    gain: float = 300.0
    """``servoL`` proportional gain (UR range [100, 2000])."""
    speed: float = 0.25
    """``servoL`` speed argument (unused by the controller in servo mode, range-checked by ur_rtde)."""
    acceleration: float = 1.2
    """``servoL`` acceleration argument (likewise unused)."""
    stop_deceleration_m_s2: float = 10.0
    """Deceleration of ``servoStop`` (m/s²)."""

    @property
    def period_s(self) -> float:
        """Streaming period (s)."""
        return 1.0 / self.rate_hz
