"""The one rollout loop: run an episode with any policy that follows SB3's ``predict`` protocol.

Classical, residual and learned controllers alike; the benchmark, the model selection, the reproduction,
the calibration and the real-cell runs all go through :func:`run_episode`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
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
    """Metrics and per-F/T-sample traces of one episode.

    Attributes:
        seed: the reset seed (None: the env's wrapper chose it).
        metrics: :data:`drillgym.envs.metrics.METRIC_NAMES`.
        trace: per-F/T-sample traces (empty without ``keep_trace``).
        steps: agent steps taken.
        sim_time_s: env time at the end (s).
        failure: ``""``, the env's failure (e.g. ``"force_limit"``) or ``"truncated"``.
        info: the last step's ``info`` (a real cell's ``error``, stop result, ...).
        rewards: the env's reward of each step.
    """

    seed: int | None
    metrics: dict[str, float]
    trace: dict[str, np.ndarray]
    steps: int = 0
    sim_time_s: float = math.nan
    failure: str = ""
    info: dict[str, Any] = field(default_factory=dict)
    rewards: np.ndarray = field(default_factory=lambda: np.zeros(0))

    def row(self) -> dict[str, Any]:
        """The metrics plus ``steps``, ``sim_time_s`` and ``failure``: one row of a benchmark table."""
        return {**self.metrics, "steps": self.steps, "sim_time_s": self.sim_time_s, "failure": self.failure}


def run_episode(
    env: gym.Env,
    policy: PolicyPredictor | None = None,
    seed: int | None = 0,
    keep_trace: bool = True,
    options: dict[str, Any] | None = None,
) -> EpisodeResult:
    """Reset with ``seed`` (and ``options``) and run to the end; ``policy=None`` commands zero correction, nominal feed.

    A policy with a ``set_plan`` method (every :class:`drillgym.controllers.Controller`) is handed the
    episode's plan after the reset, as the benchmark does. ``seed=None`` leaves the seed to the env (a
    wrapper such as ``ScenarioCycle`` sets its own).
    """
    obs, _ = env.reset(seed=seed, options=options)
    if policy is not None and hasattr(policy, "set_plan"):
        policy.set_plan(env.unwrapped.plan)  # type: ignore[attr-defined]
    state, start, steps = None, True, 0
    rewards: list[float] = []
    zero = np.zeros(ACTION_DIM, dtype=np.float32)
    while True:
        if policy is None:
            action = zero
        else:
            action, state = policy.predict(obs, state=state, episode_start=np.array([start]), deterministic=True)
        obs, reward, terminated, truncated, info = env.step(action)
        rewards.append(float(reward))
        start, steps = False, steps + 1
        if terminated or truncated:
            break
    metrics = info.get("metrics") or env.unwrapped.episode_metrics()  # type: ignore[attr-defined]
    failure = info.get("failure") or ("truncated" if truncated and not terminated else "")
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
    t_s = float(info.get("t_s", math.nan))
    return EpisodeResult(seed, dict(metrics), trace, steps, t_s, str(failure), dict(info), np.asarray(rewards))
