"""A reward paired with the base controller's own episode: common random numbers for residual training.

Against a strong base, a residual's gain is a few hundredths of a millimetre, while the reward of one
episode swings by far more with the episode's specimen, noise and scenario. :class:`PairedReward` takes
that swing out: every training episode is reset with an explicit seed, the base controller drills the same
scenario on the same seed in a twin env (the same specimen and noise), and the agent is rewarded with the
difference ``r_t - b_t`` between its step reward and the base's reward at the same step. When the agent's
episode ends, the base's remaining rewards are subtracted at once, so the episode's return is exactly the
agent's return minus the base's: a constant per seed that no action changes, i.e. the optimal policy is that
of the unpaired reward. With a zero residual every step's paired reward is 0.

The twin is a second simulated env with the same arguments; the base's episode costs one extra episode of
the base controller per training episode (the learner's gradient steps cost far more). Training only: the
policy observes what it did before; the twin's state never enters the observation.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import gymnasium as gym
import numpy as np

from drillgym.controllers import make_controller
from drillgym.controllers.rollout import run_episode
from drillgym.envs.effects.registry import build_effects
from drillgym.envs.seeds import Purpose, draw_seed, training_stream


def base_step_rewards(
    twin: gym.Env, base: str, seed: int, scenario: dict[str, Any], cell: str | None = None
) -> np.ndarray:
    """The base controller's step rewards on ``scenario`` reset with ``seed`` (one per agent step).

    ``cell``: the episode's effect spec (drawn by :class:`drillgym.training.cell.CellDraws`); None keeps the twin's own.
    """
    options: dict[str, Any] = {"scenario": scenario}
    if cell is not None:
        options["effects"] = build_effects(cell) if cell else []
    return run_episode(twin, make_controller(base), seed, keep_trace=False, options=options).rewards


class PairedReward(gym.Wrapper):
    """Reward each step relative to the base controller's episode on the same seed and scenario.

    Args:
        env: the training env (a :class:`drillgym.training.domain_randomization.DomainRandomization` around the
            simulated env: the scenario it draws is read back from ``env.unwrapped.scenario``). Below the
            :class:`drillgym.training.residual_wrapper.ResidualWrapper`.
        base: the base controller's spec (the residual's base).
        make_twin: builds the twin env (the simulated env with the training env's arguments).
        stream_keys: keys of the seed draws' generator (:func:`drillgym.envs.seeds.training_stream`): a run's seed and a worker's rank.

    ``info["reward_unpaired"]`` holds the env's own step reward. Each reset draws the episode's seed, in the
    training namespace (:mod:`drillgym.envs.seeds`), from a generator seeded by the first ``reset(seed=...)``,
    so a seeded run replays the same episodes.
    """

    def __init__(self, env: gym.Env, base: str, make_twin: Callable[[], gym.Env], stream_keys: tuple[int, ...] = ()):
        super().__init__(env)
        self.base = base
        self.stream_keys = tuple(int(k) for k in stream_keys)
        self.twin = make_twin()
        self._rng: np.random.Generator | None = None
        self.last_seed = -1
        """The seed of the current episode (drawn at reset)."""
        self.last_base_rewards = np.zeros(0)
        """The base's step rewards on the current episode."""
        self._t = 0

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[Any, dict[str, Any]]:
        """Reset with a drawn episode seed and run the base on the same episode in the twin."""
        if seed is not None or self._rng is None:
            self._rng = training_stream(self.stream_keys, seed)
        self.last_seed = draw_seed(self._rng, Purpose.TRAIN)
        obs, info = self.env.reset(seed=self.last_seed, options=options)
        scenario = self.env.unwrapped.scenario.to_dict()  # type: ignore[attr-defined]
        self.last_base_rewards = base_step_rewards(self.twin, self.base, self.last_seed, scenario, info.get("cell"))
        self._t = 0
        return obs, {**info, "episode_seed": self.last_seed}

    def step(self, action: Any) -> tuple[Any, float, bool, bool, dict[str, Any]]:
        """The env's step with the reward minus the base's at this step (and the base's rest at the end)."""
        obs, reward, terminated, truncated, info = self.env.step(action)
        rest = self.last_base_rewards[self._t :]
        paired = float(reward) - (float(rest[0]) if len(rest) else 0.0)
        self._t += 1
        if terminated or truncated:
            paired -= float(np.add.reduce(rest[1:]))  # 0.0 when the base ended first
        return obs, paired, terminated, truncated, {**info, "reward_unpaired": float(reward)}

    def close(self) -> None:
        """Close the twin and the env."""
        self.twin.close()
        super().close()
