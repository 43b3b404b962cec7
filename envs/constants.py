"""Rates, scales and limits shared by the simulated and the real cell. All scaling lives here."""

from __future__ import annotations

from typing import Any

import numpy as np

CONTROL_DT_S = 0.05
"""Agent step (s): 20 Hz. Li's controller runs on top of it (a path point every 12 steps = 600 ms)."""
FT_RATE_HZ = 100.0
"""F/T sampling rate (Hz), Li's ATI Mini40 acquisition."""
PHYSICS_DT_S = 1.0 / FT_RATE_HZ
"""Quasi-static physics update (s): one solve per F/T sample."""
SUBSTEPS_PER_STEP = round(CONTROL_DT_S / PHYSICS_DT_S)
"""F/T samples (and physics updates) per agent step."""
RTDE_RATE_HZ = 125.0
"""UR CB3 real-time data exchange rate (Hz)."""
TRACKER_RATE_HZ = 60.0
"""Optical tracker (NDI Polaris-class) update rate (Hz)."""

MAX_CORRECTION_M = 2e-3
"""Action[0:3] = ±1 maps to ±2 mm of drill-tip target correction per base axis (m)."""
FEED_OVERRIDE_LOG2_MAX = 2.0
"""Action[3] = a maps to a feed scale of 2**(a · 2): 1/4 to 4 times the nominal feed."""
ACTION_DIM = 4

FT_RESOLUTION = np.array([0.01, 0.01, 0.02, 1.25e-4, 1.25e-4, 1.25e-4])
"""ATI Mini40 (SI-40-2) resolution: N for Fx, Fy, Fz; N·m for the torques (Li §3.2)."""
FT_TORQUE_NOISE_ARM_M = 0.005
"""Torque noise std = force noise std × this arm (m), a Mini40-like noise ratio."""

APPROACH_START_M = 3e-3
"""Tip standoff above the planned entry point, along the axis, at the start of an episode (m)."""
FEED_START_M = 0.2e-3
"""Standoff at which the approach hands over to the drilling feed (m)."""
APPROACH_SPEED_M_S = 2e-3
"""Approach speed along the axis (m/s)."""
RETRACT_SPEED_M_S = 10e-3
"""Retract speed along the axis (m/s)."""

FORCE_LIMIT_N = 40.0
"""Default safety limit on the measured force magnitude (N): the episode ends (failure)."""
MAX_EPISODE_STEPS = 4000
"""Registration time limit in agent steps (200 s of simulated time)."""


def scale_action(action: np.ndarray) -> tuple[np.ndarray, Any]:
    """Map a clipped action in [-1, 1]^4 to (tip correction in the base frame (m), feed scale (-)).

    One action gives a (3,) correction and a float; a batch (N, 4) gives (N, 3) corrections and (N,) scales.
    """
    a = np.asarray(action, dtype=float)
    if a.ndim == 1:  # Python floats, as cheap as it gets in the single env's step (the same products as numpy's)
        x0, x1, x2, x3 = a.tolist()
        m = MAX_CORRECTION_M
        return np.array([m * x0, m * x1, m * x2]), float(2.0 ** (FEED_OVERRIDE_LOG2_MAX * x3))
    return MAX_CORRECTION_M * a[:, :3], 2.0 ** (FEED_OVERRIDE_LOG2_MAX * a[:, 3])


def scaled_rows(actions: np.ndarray) -> np.ndarray:
    """:func:`scale_action` of each row of ``actions`` (T, 4), bit for bit, as (T, 4) rows: correction (m), feed scale.

    The corrections are elementwise products (as one row's); each feed scale is a float's power, as the single
    step's (numpy's array power may round differently), without a Python call per row.
    """
    a = np.asarray(actions, dtype=float)
    out = np.empty((len(a), 4))
    out[:, :3] = MAX_CORRECTION_M * a[:, :3]
    out[:, 3] = [2.0 ** (FEED_OVERRIDE_LOG2_MAX * x) for x in a[:, 3].tolist()]
    return out


def unscale_action(correction_base_m: np.ndarray, feed_scale: float = 1.0) -> np.ndarray:
    """Inverse of :func:`scale_action`, clipped to the action box (float32)."""
    a = np.empty(ACTION_DIM)
    a[:3] = np.asarray(correction_base_m, dtype=float) / MAX_CORRECTION_M
    a[3] = np.log2(max(feed_scale, 1e-9)) / FEED_OVERRIDE_LOG2_MAX
    return np.clip(a, -1.0, 1.0).astype(np.float32)
