"""Helpers of the physics tests: one uncompensated episode, and the R² of a straight-line fit."""

from __future__ import annotations

import gymnasium as gym
import numpy as np

from drillgym import envs  # noqa: F401  (registers the ids)
from drillgym.controllers.rollout import EpisodeResult, run_episode

ENV_ID = "drillgym/UR5BoneDrill-v1"


def run_zero_action(seed: int = 0, **scenario) -> EpisodeResult:
    """One uncompensated episode of a scenario; the env is closed afterwards."""
    env = gym.make(ENV_ID, **scenario)
    try:
        return run_episode(env, None, seed)
    finally:
        env.close()


def r_squared(x: np.ndarray, y: np.ndarray) -> float:
    """Coefficient of determination of a least-squares straight line through (x, y)."""
    coef = np.polyfit(x, y, 1)
    resid = y - np.polyval(coef, x)
    return 1.0 - float(resid @ resid) / float(((y - y.mean()) ** 2).sum())
