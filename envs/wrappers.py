"""Wrappers for the sim env."""

from __future__ import annotations

from typing import Any, SupportsFloat

import gymnasium as gym


class MetricsOnTruncation(gym.Wrapper, gym.utils.RecordConstructorArgs):
    """Puts the episode metrics in ``info`` when a wrapper inside (Gymnasium's ``TimeLimit``) truncates the episode.

    The env reports them itself when it ends the episode (``info["metrics"]``, ``info["metrics_truncated"]``);
    a ``TimeLimit`` of ``gym.make(..., max_episode_steps=N)`` shorter than the env's own limit truncates without
    them. Then this adds :meth:`~drillgym.envs.drill_env.UR5BoneDrillEnv.episode_metrics` (the part drilled)
    with ``metrics_truncated = True``::

        env = MetricsOnTruncation(gym.make("drillgym/UR5BoneDrill-v1", max_episode_steps=200))

    Not applied by ``gym.make`` itself: a registered additional wrapper would stop
    ``gym.make_vec(..., vectorization_mode="vector_entry_point")`` (Gymnasium refuses the two together).
    """

    def __init__(self, env: gym.Env) -> None:
        gym.utils.RecordConstructorArgs.__init__(self)
        gym.Wrapper.__init__(self, env)

    def step(self, action: Any) -> tuple[Any, SupportsFloat, bool, bool, dict[str, Any]]:
        """The env's step; on a truncation without metrics, the metrics of the episode so far."""
        obs, reward, terminated, truncated, info = self.env.step(action)
        if truncated and not terminated and "metrics" not in info:
            info = {**info, "metrics": self.env.unwrapped.episode_metrics(), "metrics_truncated": True}  # type: ignore[attr-defined]
        return obs, reward, terminated, truncated, info
