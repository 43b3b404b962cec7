"""Observation space of the drilling cell: only what the real cell measures.

Shared by the simulated and the real env, so a policy trained in one runs unchanged on the other.
"""

from __future__ import annotations

import numpy as np
from gymnasium import spaces

from drillgym.envs.constants import FEED_OVERRIDE_LOG2_MAX

OBS_BOUNDS: dict[str, tuple[int, float]] = {
    "ft_wrench": (6, 500.0),
    "ft_wrench_mean": (6, 500.0),
    "q_rad": (6, 2.0 * np.pi),
    "tcp_error_base_m": (3, 0.1),
    "tracker_error_base_m": (3, 0.1),
    "tracker_valid": (1, 1.0),
    "path_depth_m": (1, 0.1),
    "phase": (3, 1.0),
    "correction_base_m": (3, 0.01),
    "feed_scale": (1, 2.0**FEED_OVERRIDE_LOG2_MAX),
}
"""Observation keys -> (size, bound). See the env docstring for meaning, frame and unit."""
_NONNEG_KEYS = ("tracker_valid", "phase", "feed_scale")


def observation_space() -> spaces.Dict:
    """The Dict observation space (float32 Boxes)."""
    return spaces.Dict(
        {k: spaces.Box(0.0 if k in _NONNEG_KEYS else -b, b, (n,), np.float32) for k, (n, b) in OBS_BOUNDS.items()}
    )


_KEYS = tuple(OBS_BOUNDS)
_SIZES = [n for n, _ in OBS_BOUNDS.values()]
_OFFSETS = np.cumsum([0, *_SIZES])
_HI = np.concatenate([np.full(n, b) for n, b in OBS_BOUNDS.values()])
_LO = np.concatenate([np.full(n, 0.0 if k in _NONNEG_KEYS else -b) for k, (n, b) in OBS_BOUNDS.items()])


OBS_SIZE = int(_OFFSETS[-1])
"""Length of the flat observation (the entries of :data:`OBS_BOUNDS` in order)."""
OBS_LOW, OBS_HIGH = _LO, _HI
"""Each flat entry's box (float64, length :data:`OBS_SIZE`)."""
_PARTS = [(k, slice(int(_OFFSETS[i]), int(_OFFSETS[i + 1]))) for i, k in enumerate(_KEYS)]
OBS_COLUMN: dict[str, int] = {k: int(_OFFSETS[i]) for i, k in enumerate(_KEYS)}
"""Each entry's first column in the flat observation."""


def pack_observation(values: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Cast to float32 and clip each entry into its box (a saturated sensor, never out of space)."""
    return pack_flat_observation(np.concatenate([np.ravel(values[k]) for k in _KEYS]))


def observation_of(
    ft_wrench: np.ndarray,
    ft_wrench_mean: np.ndarray,
    q_rad: np.ndarray,
    tcp_error_base_m: np.ndarray,
    tracker_error_base_m: np.ndarray | float,
    tracker_valid: float,
    path_depth_m: float | np.ndarray,
    phase: int | np.ndarray,
    correction_base_m: np.ndarray,
    feed_scale: float | np.ndarray,
    num_envs: int | None = None,
) -> dict[str, np.ndarray]:
    """The packed observation from its entries (:data:`OBS_BOUNDS`; ``phase`` the path phase's code, one-hot here).

    One episode (``num_envs`` None): floats and (k,) arrays. A batch of ``num_envs``: ``path_depth_m``, ``phase``
    and ``feed_scale`` of shape (N,), the others (N, k) (or broadcastable); every returned array has N rows.
    """
    flat = np.empty(OBS_SIZE if num_envs is None else (num_envs, OBS_SIZE))  # OBS_BOUNDS' entries end to end
    flat[..., 0:6] = ft_wrench
    flat[..., 6:12] = ft_wrench_mean
    flat[..., 12:18] = q_rad
    flat[..., 18:21] = tcp_error_base_m
    flat[..., 21:24] = tracker_error_base_m
    flat[..., 24] = tracker_valid
    flat[..., 25] = path_depth_m
    flat[..., 26:29] = 0.0  # one-hot: approach, feed, retract (or done)
    if num_envs is None:
        flat[26 + min(int(phase), 2)] = 1.0
    else:
        flat[np.arange(num_envs), 26 + np.minimum(phase, 2)] = 1.0
    flat[..., 29:32] = correction_base_m
    flat[..., 32] = feed_scale
    return pack_flat_observation(flat)


def pack_flat_observation(flat: np.ndarray) -> dict[str, np.ndarray]:
    """:func:`pack_observation` of the entries already laid end to end (float64, :data:`OBS_BOUNDS` order).

    Clips ``flat`` in place; the returned arrays are views of one new float32 array. A batch of observations
    (one row each) gives arrays with the same leading axis.
    """
    np.maximum(flat, _LO, out=flat)  # np.clip(flat, _LO, _HI, out=flat), without its Python wrapper
    return unpack_observation(np.minimum(flat, _HI, out=flat).astype(np.float32))


def unpack_observation(flat: np.ndarray) -> dict[str, np.ndarray]:
    """The observation's entries as views of ``flat`` (float32, already clipped; one row per episode of a batch)."""
    if flat.ndim == 1:
        return {k: flat[part] for k, part in _PARTS}
    return {k: flat[:, part] for k, part in _PARTS}
