"""What an episode's named state (:mod:`drillgym.envs.episode_state`) shows: the observation and the info.

The batched env's views of its episodes' arrays, equal bit for bit to what the single env shows from its Python
objects (``tests/envs/test_batched.py``). Units: SI; frames as named (base, task, sensor).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from drillgym.envs.observation import observation_of


def observation_from_state(
    state: np.ndarray, params: np.ndarray, tracking: np.ndarray, tracker_fitted: bool
) -> dict[str, np.ndarray]:
    """The observation of N episodes (:data:`~drillgym.envs.observation.OBS_BOUNDS`, one row each).

    Args:
        state: the episodes' :data:`~drillgym.envs.episode_state.STATE` records (N,).
        params: their :data:`~drillgym.envs.episode_state.PARAMS` records (N,).
        tracking: (N,) whether each episode's tracker has reported (it has taken a step).
        tracker_fitted: whether the cell has a tracker (the ``tracker_valid`` entry; without one the error is 0).
    """
    s = state["path_m"]
    nominal = params["entry_base_m"] + params["R_base_task"][:, :, 2] * s[:, None]  # entry + R_base_task · (0, 0, s)
    return observation_of(
        state["ft_last"],
        state["ft_mean"],
        state["q_motor_rad"],
        state["rtde_tcp_base_m"] - nominal,
        np.where((tracking & tracker_fitted)[:, None], state["tracker_error_base_m"], 0.0),
        1.0 if tracker_fitted else 0.0,
        s,
        state["phase"],
        state["correction_base_m"],
        state["feed_scale"],
        len(state),
    )


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
