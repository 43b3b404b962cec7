"""The channels the diagnosis compares, the drilling stages it compares them in, and their scales.

Low-frequency (LF) channels are compared as 0.1 s block means; high-frequency (HF) channels are the
power of a force axis about its block means (what a once-per-revolution force or chatter adds). Every
channel is something a real cell records (F/T, tracker, RTDE joint angles); the tracker is expressed
in the task frame (x uphill, y across, z along the planned drill axis) so its axes mean something.
"""

from __future__ import annotations

FORCE_CHANNELS = ("fx_n", "fy_n", "fz_n")
"""F/T force (N, sensor frame)."""
TORQUE_CHANNELS = ("tx_nm", "ty_nm", "tz_nm")
"""F/T torque about the sensor origin (N·m, sensor frame)."""
TRACKER_CHANNELS = ("tracker_x_task_m", "tracker_y_task_m", "tracker_z_task_m")
"""Tracker marker position relative to the planned entry point (m, task frame)."""
Q_CHANNELS = tuple(f"q{i}_rad" for i in range(6))
"""RTDE joint angles (rad, motor side)."""
LF_CHANNELS = FORCE_CHANNELS + TORQUE_CHANNELS + TRACKER_CHANNELS + Q_CHANNELS
"""Channels compared as block means, in column order."""


def _columns(channels: tuple[str, ...]) -> slice:
    start = LF_CHANNELS.index(channels[0])
    return slice(start, start + len(channels))


FORCE = _columns(FORCE_CHANNELS)
"""Columns of the F/T force in an (n, len(LF_CHANNELS)) array of LF channels."""
TORQUE = _columns(TORQUE_CHANNELS)
"""Columns of the F/T torque."""
WRENCH = _columns(FORCE_CHANNELS + TORQUE_CHANNELS)
"""Columns of the F/T force and torque."""
TRACKER = _columns(TRACKER_CHANNELS)
"""Columns of the tracker marker (task frame)."""
Q = _columns(Q_CHANNELS)
"""Columns of the RTDE joint angles."""

HF_CHANNELS = ("fx_hf_n", "fy_hf_n", "fz_hf_n")
"""Power of each force axis about its 0.1 s block means (reported as RMS, N)."""
ALL_CHANNELS = LF_CHANNELS + HF_CHANNELS

LF_FLOOR = {
    **dict.fromkeys(FORCE_CHANNELS, 0.005),
    **dict.fromkeys(TORQUE_CHANNELS, 5e-5),
    **dict.fromkeys(TRACKER_CHANNELS, 1e-5),
    **dict.fromkeys(Q_CHANNELS, 2e-5),
}
"""Smallest scale of a channel's block-mean gap (its unit): the sensor's resolution or a real encoder's
noise, so a channel the simulator reproduces exactly (joint angles) is not divided by zero."""
HF_LOG_VAR_FLOOR = 0.02
"""Smallest variance of the log of an HF power (a 14 % power mismatch is one standard deviation)."""
HF_POWER_FLOOR_N2 = 1e-6
"""Added to HF powers before their logs are compared (N²)."""

GROUP_OF = {
    **dict.fromkeys(FORCE_CHANNELS + HF_CHANNELS, "force"),
    **dict.fromkeys(TORQUE_CHANNELS, "torque"),
    **dict.fromkeys(TRACKER_CHANNELS, "tracker"),
    **dict.fromkeys(Q_CHANNELS, "q"),
}
"""Channel group of each channel (the groups of :data:`drillgym.envs.effects.CHANNEL_GROUPS`)."""

STAGES = ("approach", "entry1", "entry2", "entry3", "stable", "retract")
"""Drilling stages estimated from the commanded depth: before contact, Li's entry stages 1–3 (lips partly
engaged; outer corner in over < ½ and ≥ ½ of a turn), fully engaged, and the retract."""

BLOCK_SAMPLES = 10
"""F/T samples per LF block (0.1 s at 100 Hz): block means reject the aliased once-per-rev force."""
