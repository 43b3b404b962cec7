"""Run episodes with any policy that follows SB3's ``predict`` protocol (classical, residual, learned)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol

import gymnasium as gym
import numpy as np

from drillgym import envs  # noqa: F401  (registers the ids)
from drillgym.envs.constants import ACTION_DIM


class PolicyPredictor(Protocol):
    """SB3's predictor protocol: what ``evaluate_policy`` and our benchmarks call."""

    def predict(
        self,
        observation: Any,
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = True,
    ) -> tuple[np.ndarray, Any]:
        """Action for ``observation`` (and the recurrent state, unused by stateless policies)."""
        ...


@dataclass
class EpisodeResult:
    """Metrics and per-F/T-sample traces of one episode."""

    seed: int
    metrics: dict[str, float]
    trace: dict[str, np.ndarray]


def run_episode(
    env: gym.Env, policy: PolicyPredictor | None = None, seed: int = 0, keep_trace: bool = True
) -> EpisodeResult:
    """Reset with ``seed`` and run to the end; ``policy=None`` commands zero correction, nominal feed.

    A policy with a ``set_plan`` method (every :class:`drillgym.controllers.Controller`) is handed the
    episode's plan after the reset, as the benchmark does.
    """
    obs, _ = env.reset(seed=seed)
    if policy is not None and hasattr(policy, "set_plan"):
        policy.set_plan(env.unwrapped.plan)  # type: ignore[attr-defined]
    state, start = None, True
    zero = np.zeros(ACTION_DIM, dtype=np.float32)
    while True:
        if policy is None:
            action = zero
        else:
            action, state = policy.predict(obs, state=state, episode_start=np.array([start]), deterministic=True)
        obs, _, terminated, truncated, info = env.step(action)
        start = False
        if terminated or truncated:
            break
    metrics = info.get("metrics") or env.unwrapped.episode_metrics()  # type: ignore[attr-defined]
    trace: dict[str, np.ndarray] = {}
    if keep_trace:
        rec = env.unwrapped.recorder  # type: ignore[attr-defined]
        trace = {
            "t_s": np.asarray(rec.t_s),
            "phase": np.asarray(rec.phase),
            "stage": np.asarray(rec.stage),
            "depth_cmd_m": np.asarray(rec.depth_cmd_m),
            "deviation_m": np.asarray(rec.deviation_m),
            "ft_force_n": np.asarray(rec.ft_force_n),
        }
    return EpisodeResult(seed, dict(metrics), trace)
