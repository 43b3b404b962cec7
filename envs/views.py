"""What an episode's named state (:mod:`drillgym.envs.episode_state`) shows: the observation and the info.

The views of the compiled step's episodes (the single env's one, the batched env's N), written once for both and
equal bit for bit to what the single env shows from its Python objects on the Python step
(``tests/envs/test_batched.py``, ``tests/envs/test_step_kernel.py``). Units: SI; frames as named (base, task,
sensor).
"""

from __future__ import annotations

import math
from typing import Any

import numba
import numpy as np

from drillgym.envs.observation import OBS_HIGH, OBS_LOW, OBS_SIZE, unpack_observation


@numba.njit(cache=True)
def observation_rows(
    state: np.ndarray, params: np.ndarray, tracking: np.ndarray, tracker_fitted: bool, out: np.ndarray
) -> None:  # pragma: no cover (compiled)
    """Each episode's flat observation (:data:`~drillgym.envs.observation.OBS_BOUNDS` end to end) into ``out`` (N, 33).

    :func:`drillgym.envs.observation.observation_of`'s entries, clipped into their boxes (float64; the caller
    casts). The TCP error is the RTDE TCP minus the nominal path point, ``entry + R_base_task (0, 0, s)``.
    """
    lo, hi = OBS_LOW, OBS_HIGH
    for i in range(state.shape[0]):
        s, p, row = state[i], params[i], out[i]
        path_m = s.path_m
        for k in range(6):
            row[k] = s.ft_last[k]
            row[6 + k] = s.ft_mean[k]
            row[12 + k] = s.q_motor_rad[k]
        for k in range(3):
            row[18 + k] = s.rtde_tcp_base_m[k] - (p.entry_base_m[k] + p.R_base_task[k, 2] * path_m)
            row[21 + k] = s.tracker_error_base_m[k] if tracking[i] and tracker_fitted else 0.0
            row[29 + k] = s.correction_base_m[k]
        row[24] = 1.0 if tracker_fitted else 0.0
        row[25] = path_m
        row[26] = row[27] = row[28] = 0.0  # one-hot: approach, feed, retract (or done)
        row[26 + min(s.phase, 2)] = 1.0
        row[32] = s.feed_scale
        for k in range(OBS_SIZE):  # np.minimum(np.maximum(x, lo), hi): NaN stays NaN
            if row[k] < lo[k]:
                row[k] = lo[k]
            if row[k] > hi[k]:
                row[k] = hi[k]


def observation_from_state(
    state: np.ndarray, params: np.ndarray, tracking: np.ndarray, tracker_fitted: bool, num_envs: int | None = None
) -> dict[str, np.ndarray]:
    """The observation of N episodes (:data:`~drillgym.envs.observation.OBS_BOUNDS`, one row each).

    Args:
        state: the episodes' :data:`~drillgym.envs.episode_state.STATE` records (N,).
        params: their :data:`~drillgym.envs.episode_state.PARAMS` records (N,).
        tracking: (N,) whether each episode's tracker has reported (it has taken a step).
        tracker_fitted: whether the cell has a tracker (the ``tracker_valid`` entry; without one the error is 0).
        num_envs: None for the single env's observation of its one episode (entries without the episode axis).
    """
    flat = np.empty((len(state), OBS_SIZE))
    observation_rows(state, params, tracking, tracker_fitted, flat)
    return unpack_observation(flat.astype(np.float32) if num_envs is not None else flat[0].astype(np.float32))


def privileged_info(state: np.ndarray, i: int) -> dict[str, Any]:
    """Episode ``i``'s privileged ``info`` entries from the state records: time, phase, stage, true tip and force."""
    s = state[i]
    sample = s["sample"]
    return {
        "t_s": float(s["t_s"]),
        "phase": int(s["phase"]),
        "stage": int(sample[11]),
        "depth_cmd_m": float(s["path_m"]),
        "tip_pos_task_m": sample[0:3].copy(),
        "deviation_m": math.hypot(sample[0], sample[1]),
        "force_true_n": sample[6:9].copy(),
        "failure": "force_limit" if s["failure"] else None,
    }
