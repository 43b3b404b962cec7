"""``none``: the uncompensated baseline (zero correction, nominal feed)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from drillgym.controllers.base import Controller
from drillgym.envs.constants import ACTION_DIM


@dataclass
class NoCompensationConfig:
    """No parameters: the robot follows the nominal path."""


class NoCompensation(Controller):
    """Zero correction and nominal feed, every step."""

    name = "none"
    batchable = True

    def __init__(self, config: NoCompensationConfig | None = None) -> None:
        super().__init__()
        self.config = config or NoCompensationConfig()

    def reset(self) -> None:
        """Nothing to forget."""

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        """Zero action."""
        return np.zeros(ACTION_DIM, dtype=np.float32)

    def act_batch(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        """Zero actions, one row per episode."""
        return np.zeros((self.num_episodes, ACTION_DIM), dtype=np.float32)
