"""Safety checks of the real cell, as pure functions of measured values (testable without hardware).

Every check returns ``None`` when all is well, or a :class:`Fault` naming the reason and what was seen.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from drillgym.envs.real.config import SafetyLimits

SAFETY_STATUS_BITS = {
    2: "protective stop",
    3: "recovery mode",
    4: "safeguard stop",
    5: "system emergency stop",
    6: "robot emergency stop",
    7: "emergency stop",
    8: "safety violation",
    9: "safety fault",
    10: "stopped due to safety",
}
"""``safety_status_bits`` that stop the episode, bit -> meaning (UR RTDE guide)."""
PROGRAM_PLAYING = 2
"""``runtime_state`` of a running program."""


@dataclass(frozen=True)
class Fault:
    """Why an episode had to stop."""

    reason: str
    """Short machine-readable reason: ``protective_stop``, ``force_limit``, ``link_lost``, ``ft_stale``, ..."""
    message: str
    """What was seen, with values and units."""
    t_s: float = float("nan")
    """Episode time of the detection (s)."""


def check_safety_bits(safety_status_bits: int, t_s: float) -> Fault | None:
    """A stop for any stopping safety bit (protective stop first)."""
    active = [name for bit, name in SAFETY_STATUS_BITS.items() if safety_status_bits >> bit & 1]
    if not active:
        return None
    reason = "protective_stop" if safety_status_bits >> 2 & 1 else "safety_stop"
    msg = f"robot reports {', '.join(active)} (safety_status_bits 0x{safety_status_bits:x}); clear it on the pendant"
    return Fault(reason, msg, t_s)


def check_workspace(
    point_task_m: np.ndarray, depth_m: float, limits: SafetyLimits, what: str, t_s: float
) -> Fault | None:
    """A stop if ``point_task_m`` (m, task frame) leaves the workspace box."""
    x, y, z = (float(v) for v in point_task_m)
    lat = limits.workspace_lateral_m
    if abs(x) <= lat and abs(y) <= lat and -limits.workspace_above_m <= z <= depth_m + limits.workspace_below_m:
        return None
    msg = (
        f"{what} at task ({x * 1e3:.2f}, {y * 1e3:.2f}, {z * 1e3:.2f}) mm is outside the workspace box "
        f"|x|,|y| <= {lat * 1e3:.1f} mm, z in [{-limits.workspace_above_m * 1e3:.1f}, "
        f"{(depth_m + limits.workspace_below_m) * 1e3:.1f}] mm"
    )
    return Fault("workspace", msg, t_s)


def check_force(wrench_n: np.ndarray, force_limit_n: float, t_s: float) -> Fault | None:
    """A stop if the measured force magnitude exceeds the limit."""
    f = float(np.linalg.norm(np.asarray(wrench_n, dtype=float)[:3]))
    if f <= force_limit_n:
        return None
    return Fault("force_limit", f"measured force {f:.2f} N exceeds the limit {force_limit_n:.2f} N", t_s)


def check_age(name: str, age_s: float | None, limit_s: float, t_s: float) -> Fault | None:
    """A stop if a stream's newest data is older than ``limit_s`` (``None``: never received)."""
    if age_s is not None and age_s <= limit_s:
        return None
    seen = "no data received" if age_s is None else f"newest data {age_s * 1e3:.0f} ms old"
    return Fault(f"{name}_stale", f"{name} stream stale: {seen} (limit {limit_s * 1e3:.0f} ms)", t_s)


def check_tracking(tcp_base_m: np.ndarray, target_base_m: np.ndarray, limits: SafetyLimits, t_s: float) -> Fault | None:
    """A stop if the measured TCP is too far from the servo target."""
    err = float(np.linalg.norm(np.asarray(tcp_base_m) - np.asarray(target_base_m)))
    if err <= limits.max_tracking_error_m:
        return None
    msg = f"TCP is {err * 1e3:.2f} mm from its servo target (limit {limits.max_tracking_error_m * 1e3:.1f} mm)"
    return Fault("tracking", msg, t_s)


def rate_limit(previous_m: np.ndarray, target_m: np.ndarray, max_step_m: float) -> np.ndarray:
    """``target_m`` moved toward from ``previous_m`` by at most ``max_step_m`` (m)."""
    delta = np.asarray(target_m, dtype=float) - previous_m
    n = float(np.linalg.norm(delta))
    return np.asarray(target_m, dtype=float) if n <= max_step_m else previous_m + delta * (max_step_m / n)


def clip_correction(correction_base_m: np.ndarray, limits: SafetyLimits) -> np.ndarray:
    """Correction clipped to ``max_correction_m`` per base axis (m)."""
    return np.clip(np.asarray(correction_base_m, dtype=float), -limits.max_correction_m, limits.max_correction_m)
